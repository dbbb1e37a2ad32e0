"""Runners that put the pieces together: the demo job and the paper's experiments."""
