"""Task worlds that compile to a :class:`~expertise_irl.mdp.TabularMDP`."""
