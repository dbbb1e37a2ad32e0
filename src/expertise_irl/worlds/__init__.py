"""Task worlds that compile to a :class:`~expertise_irl.mdp.TabularMDP`."""

#: The package defines no names of its own: import them from its modules.
__all__: list[str] = []
