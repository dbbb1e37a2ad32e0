"""Live tele-operation: a local page where a person drives and the estimate updates after every
action (:mod:`.session` holds the logic, :mod:`.server` the Starlette/uvicorn server)."""

#: The package defines no names of its own: import them from its modules.
__all__: list[str] = []
