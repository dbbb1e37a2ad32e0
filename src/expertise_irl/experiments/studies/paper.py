"""The paper's studies in the paper's order (Sec. VI-A, VI-E, VII, then beyond it): one entry point."""

from __future__ import annotations

from .cardinality import STUDY as CARDINALITY
from .fixed_vs_joint import STUDY as CONDITIONS
from .fullset import STUDY as FULLSET
from .optimisation import STUDY as OPTIMISATION

STUDIES = (CONDITIONS, CARDINALITY, OPTIMISATION, FULLSET)
