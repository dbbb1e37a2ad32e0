"""Every figure: zone maps (:mod:`.maps`), floor plans (:mod:`.floorplan`), result documents
(:mod:`.results`) and user-study figures (:mod:`.userstudy`). Figures are built on a
:class:`~matplotlib.figure.Figure` directly (no pyplot state) and never compute a model:
they draw what the other packages computed."""

#: The package defines no names of its own: import them from its modules.
__all__: list[str] = []
