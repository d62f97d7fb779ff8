"""The measures, declared once: name, unit, needs, direction, recipe from the sums, description.

Everything that names or derives a measure reads this table: the Python derivations
(:mod:`dispeval_ros.core.measures`), the kernels' accumulator layout
(:mod:`dispeval_ros.core.kernels.layout`), the report page's recipes, the CLI and ROS help
texts, the score-vector labels and the objective defaults. A new measure is one entry here
(plus its terms in a kernel when it needs new sums).

Plain data only (no numpy, no numba): help texts and parameter tables import it cheaply.
"""

from __future__ import annotations

from dataclasses import dataclass

MAX_THRESHOLDS = 8
"""Bad-pixel thresholds the accumulator holds at once: δ, then up to seven ``bad_X``."""

SUM_FIELDS: tuple[str, ...] = (
    "n",
    "n_valid",
    "n_eval",
    "sum_e",
    "sum_e2",
    "sum_rel",
    "sze",
    "bmpre",
    "d1_count",
    *(f"bad_count_{i}" for i in range(MAX_THRESHOLDS)),
    "sum_ez",
    "sum_ez2",
    "sum_relz",
    "sum_iz2",
    "n_vpe",
    "sum_vpe",
    "n_lrc",
    "lrc_count",
)
"""The accumulator columns, in order (``bad_count_0`` is at δ, the others at the bad-x
thresholds; then the depth-domain sums, then the ground-truth-free sums). The kernels' integer
``FIELD_*`` constants are these positions."""

CAMERA_FIELDS = ("sze", "sum_ez", "sum_ez2", "sum_relz", "sum_iz2")
"""The sums that need the camera (f·B): SZE and the depth-domain measures."""


def field_index(name: str) -> int:
    """The column of accumulator field ``name``."""
    return SUM_FIELDS.index(name)


# What a measure needs to be scored (``core.measures.applies``): ground truth (dense disparity
# or sparse LiDAR points: the same sums), the left/right images (GT-free criteria only), or
# nothing but the estimate (on every criterion).
NEEDS_GT = "gt"
NEEDS_IMAGES = "images"
NEEDS_NONE = "none"

LOWER = "lower"
HIGHER = "higher"

# How a measure is made from a row of sums (``num``, ``den``: field names):
RATIO = "ratio"  # scale · num / den, nan unless den > 0
SQRT_RATIO = "sqrt_ratio"  # scale · sqrt(num / den) (the report page: sqrt(scale² · num / den))
TOTAL = "total"  # num
STORED = "stored"  # a per-frame quantile, not derived from sums (not summable)


@dataclass(frozen=True)
class Measure:
    """One measure (or one family: ``bad_X`` any threshold, ``aNN`` any quantile level)."""

    name: str
    unit: str
    needs: str
    kind: str
    num: str | None
    den: str | None
    scale: float
    description: str
    direction: str = LOWER
    family: str = "disparity"
    """``disparity``, ``depth`` (depth-domain, not a default of disparity GT), ``gtfree``."""
    default: bool = True
    """In the default measures (families: at the default thresholds / levels)."""
    objective: bool = False
    """A default objective of the models where scored (``core.objectives``)."""


_EVAL = "n_eval"

MEASURES: tuple[Measure, ...] = (
    Measure("bmp", "%", NEEDS_GT, RATIO, "bad_count_0", _EVAL, 100.0,
            "bad-matched pixels: share of scored points with error above δ"),
    Measure("bmp_count", "points", NEEDS_GT, TOTAL, "bad_count_0", None, 1.0,
            "bad-matched pixels: how many scored points have an error above δ"),
    Measure("bad_X", "%", NEEDS_GT, RATIO, None, _EVAL, 100.0,
            "share of scored points with error above X px (any threshold X)"),
    Measure("mae", "px", NEEDS_GT, RATIO, "sum_e", _EVAL, 1.0, "mean absolute error"),
    Measure("mse", "px²", NEEDS_GT, RATIO, "sum_e2", _EVAL, 1.0, "mean squared error"),
    Measure("rmse", "px", NEEDS_GT, SQRT_RATIO, "sum_e2", _EVAL, 1.0, "root mean squared error"),
    Measure("mre", "e/D", NEEDS_GT, RATIO, "sum_rel", _EVAL, 1.0,
            "mean relative error (error over GT disparity)"),
    Measure("sze", "m", NEEDS_GT, TOTAL, "sze", None, 1.0,
            "sum of depth errors the disparity errors cause (needs the camera)", objective=True),
    Measure("sze_mean", "m", NEEDS_GT, RATIO, "sze", _EVAL, 1.0, "SZE per scored point"),
    Measure("bmpre", "Σ e/D", NEEDS_GT, TOTAL, "bmpre", None, 1.0,
            "sum of relative errors of the bad-matched points", objective=True),
    Measure("bmpre_mean", "e/D", NEEDS_GT, RATIO, "bmpre", _EVAL, 1.0, "BMPRE per scored point"),
    Measure("d1", "%", NEEDS_GT, RATIO, "d1_count", _EVAL, 100.0,
            "KITTI D1: share of points with error above 3 px and 5 % of the GT"),
    Measure("aNN", "px", NEEDS_GT, STORED, None, None, 1.0,
            "NN-th percentile of the absolute error (any level NN; per frame only)"),
    Measure("density", "share", NEEDS_NONE, RATIO, "n_valid", "n", 1.0,
            "share of points with a valid estimate", direction=HIGHER),
    Measure("mae_z", "m", NEEDS_GT, RATIO, "sum_ez", _EVAL, 1.0,
            "mean absolute depth error", family="depth", default=False),
    Measure("rmse_z", "m", NEEDS_GT, SQRT_RATIO, "sum_ez2", _EVAL, 1.0,
            "root mean squared depth error", family="depth", default=False),
    Measure("absrel_z", "ratio", NEEDS_GT, RATIO, "sum_relz", _EVAL, 1.0,
            "mean absolute relative depth error", family="depth", default=False),
    # 1/Z in 1/km: sqrt(mean((1/Z_E − 1/Z_D)²)) · 1000 for Z in metres (KITTI's depth devkit).
    Measure("irmse", "1/km", NEEDS_GT, SQRT_RATIO, "sum_iz2", _EVAL, 1000.0,
            "root mean squared inverse-depth error", family="depth", default=False),
    Measure("vpe", "grey levels", NEEDS_IMAGES, RATIO, "sum_vpe", "n_vpe", 1.0,
            "view-prediction error: right image warped by the estimate vs the left image",
            family="gtfree", default=False, objective=True),
    Measure("lrc", "%", NEEDS_IMAGES, RATIO, "lrc_count", "n_lrc", 100.0,
            "left-right inconsistency: share of points where the right-view estimate disagrees",
            family="gtfree", default=False),
)  # fmt: skip
"""Every measure a user can choose, in the order help texts and defaults list them."""

POINTS = Measure("n", "points", NEEDS_NONE, TOTAL, "n", None, 1.0,
                 "points of the criterion (always reported)", default=False)  # fmt: skip
"""``n``: reported beside every measure, never chosen."""

BY_NAME: dict[str, Measure] = {m.name: m for m in (*MEASURES, POINTS)}
FAMILIES = ("bad_X", "aNN")
"""Names standing for a family of measures (``bad_0.5``, ``a90``, …)."""

MEASURE_NAMES = tuple(m.name for m in MEASURES)
"""What the front ends list (``bad_X``, ``aNN`` as written)."""


def names(**where: object) -> tuple[str, ...]:
    """Names of the measures whose attributes equal ``where`` (e.g. ``family="depth"``)."""
    return tuple(
        m.name for m in MEASURES if all(getattr(m, key) == value for key, value in where.items())
    )


def listing(separator: str = " ") -> str:
    """The measures for a help text, in registry order."""
    return separator.join(MEASURE_NAMES)


# -- Pair measures: consecutive frames t, t+1 of one ground-truth sequence ---------------------
# A section of its own, not entries of MEASURES: every frame front end lists, parses and scores
# MEASURES (help texts, score vectors, report recipes, objectives), so nothing prints or scores
# these until a front end scores frame pairs through ``core.temporal``.

NEEDS_GT_PAIR = "gt_pair"
"""Needs the ground truth of two consecutive frames (and both frames' estimates)."""

TEPE_R_EPSILON = 1e-3
"""px added to ``|D_t − D_t+1|`` in ``tepe_r``'s denominator (the published code's 1e-3)."""

PAIR_SUM_FIELDS: tuple[str, ...] = (
    "n_pair",
    "n_pair_eval",
    "n_pair_nonzero",
    "sum_te",
    "sum_te_rel",
    *(f"te_bad_count_{i}" for i in range(MAX_THRESHOLDS)),
)
"""The pair accumulator's columns: pixels with GT in both frames, those scored (weight 1 unless
``ignore`` drops a missing estimate), those scored with a non-zero temporal error, Σ e,
Σ e / (|ΔD| + ε), then the bad counts at δ and the bad-x thresholds (as ``bad_count_*``)."""


def pair_field_index(name: str) -> int:
    """The column of pair accumulator field ``name``."""
    return PAIR_SUM_FIELDS.index(name)


_PAIR_EVAL = "n_pair_eval"

PAIR_MEASURES: tuple[Measure, ...] = (
    Measure("tepe", "px", NEEDS_GT_PAIR, RATIO, "sum_te", _PAIR_EVAL, 1.0,
            "temporal end-point error: mean |(E_t − E_t+1) − (D_t − D_t+1)| at the same pixel "
            "(no warping), over the pixels with ground truth in both frames", family="temporal"),
    Measure("tepe_r", "e/|ΔD|", NEEDS_GT_PAIR, RATIO, "sum_te_rel", _PAIR_EVAL, 1.0,
            f"relative TEPE: mean temporal error over |D_t − D_t+1| + {TEPE_R_EPSILON:g} px",
            family="temporal"),
    Measure("tepe_bmp", "%", NEEDS_GT_PAIR, RATIO, "te_bad_count_0", _PAIR_EVAL, 100.0,
            "share of scored pixel pairs with a temporal error above δ", family="temporal"),
    Measure("tepe_bad_X", "%", NEEDS_GT_PAIR, RATIO, None, _PAIR_EVAL, 100.0,
            "share of scored pixel pairs with a temporal error above X px (any threshold X)",
            family="temporal"),
)  # fmt: skip
"""Measures of a pair of consecutive frames, summable per criterion like the frame measures."""

PAIR_BY_NAME: dict[str, Measure] = {m.name: m for m in PAIR_MEASURES}
PAIR_FAMILIES = ("tepe_bad_X",)
PAIR_MEASURE_NAMES = tuple(m.name for m in PAIR_MEASURES)
