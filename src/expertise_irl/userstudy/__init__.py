"""User studies (paper Sec. VIII): manifests of participants' tasks, the ``study`` pipeline,
its reports and figures, and simulated recordings for the bundled example."""

#: The package defines no names of its own: import them from its modules.
__all__: list[str] = []
