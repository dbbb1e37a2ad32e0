"""Shared test configuration: a headless matplotlib backend and small fixtures."""

import matplotlib

matplotlib.use("Agg")
