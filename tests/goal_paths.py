"""Shortest action sequences to a goal (shared by the live tests)."""

from __future__ import annotations

from collections import deque


def path_to_goal(mdp, s: int) -> list[int]:
    """Actions of a shortest path from state s to a goal (BFS)."""
    prev = {s: None}
    queue = deque([s])
    while queue:
        u = queue.popleft()
        if mdp.terminal[u]:
            actions = []
            while prev[u] is not None:
                p, a = prev[u]
                actions.append(a)
                u = p
            return actions[::-1]
        for a in range(mdp.n_actions):
            v = int(mdp.next_state[u, a])
            if v >= 0 and v not in prev:
                prev[v] = (u, a)
                queue.append(v)
    raise AssertionError("no path")
