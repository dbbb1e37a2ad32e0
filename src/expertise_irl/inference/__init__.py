"""Inference methods: the discrete-set belief (Eq. 13) and hypothesis-set conditions."""

#: The package defines no names of its own: import them from its modules.
__all__: list[str] = []
