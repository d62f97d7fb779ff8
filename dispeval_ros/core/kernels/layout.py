"""Column layout of the per-cell accumulator (float64), as integers the kernels compile in.

Generated from the one declaration, :data:`dispeval_ros.core.registry.SUM_FIELDS`: numba
freezes module-level integers into the compiled code, so they are plain constants here.
numba's on-disk cache is keyed by each kernel's own source file, not this one: after changing
the layout, clear the kernels' ``__pycache__`` (``test/test_registry.py`` checks the compiled
kernels write where the registry says).
"""

from __future__ import annotations

from dispeval_ros.core import registry
from dispeval_ros.core.registry import SUM_FIELDS, field_index

MAX_THRESHOLDS = registry.MAX_THRESHOLDS

FIELD_N = field_index("n")
FIELD_VALID = field_index("n_valid")
FIELD_EVAL = field_index("n_eval")
FIELD_SUM_E = field_index("sum_e")
FIELD_SUM_E2 = field_index("sum_e2")
FIELD_SUM_REL = field_index("sum_rel")
FIELD_SZE = field_index("sze")
FIELD_BMPRE = field_index("bmpre")
FIELD_D1 = field_index("d1_count")
FIELD_BAD = field_index("bad_count_0")
"""δ's bad count; the bad-x thresholds' counts follow (``MAX_THRESHOLDS`` in all)."""
# Depth-domain sums: Σ|Z_E − Z_D|, Σ(Z_E − Z_D)², Σ|Z_E − Z_D|/Z_D and Σ(1/Z_E − 1/Z_D)².
FIELD_SUM_EZ = field_index("sum_ez")
FIELD_SUM_EZ2 = field_index("sum_ez2")
FIELD_SUM_RELZ = field_index("sum_relz")
FIELD_SUM_IZ2 = field_index("sum_iz2")
# Ground-truth-free sums (core/gtfree.py): pixels in the view-prediction error and their
# Σ|I_L − I_R(x − d)|, pixels left-right checked and the inconsistent ones among them.
FIELD_N_VPE = field_index("n_vpe")
FIELD_SUM_VPE = field_index("sum_vpe")
FIELD_N_LRC = field_index("n_lrc")
FIELD_LRC = field_index("lrc_count")
FIELD_COUNT = len(SUM_FIELDS)
