"""Choices and defaults of options, declared once for the library and the command line.

The modules that use them import them from here (and still offer them under their old
names: ``tromplab.curves.ranking.RANK_BY`` is this ``RANK_BY``).  This module imports
nothing, so the command line builds its parser, and answers ``--version`` and ``-h``,
without importing the numerical libraries behind the commands.
"""

# --- lab tables (tromplab.loading.lab) ---------------------------------------------------
#: What plain feed/fine/coarse columns of a lab table may hold.
KINDS = ("mass", "pct", "frac", "retained_pct", "retained_frac", "passing_pct", "passing_frac")
#: How the partition of three measured streams is computed: from both products or from the feed.
PARTITION_METHODS = ("products", "feed")
#: Allowed deviation of per-class percentages from 100 (percentage points).
DEFAULT_SUM_TOLERANCE_PCT = 1.5
#: Classes with a smaller feed share (fraction) are left out of the fit.
DEFAULT_MIN_FEED_SHARE = 0.002
#: How Tromp points are weighted in the fit (tromplab.loading.weights): every class alike, by its
#: feed share, or by the inverse variance of its partition under the error model of the analyses.
WEIGHTINGS = ("none", "feed-share", "error-model")
#: Partition standard deviation added for a class of average feed share under the "error-model"
#: weighting (scaled by the inverse feed share), so that no class is taken as exact.
DEFAULT_PARTITION_FLOOR = 0.03
#: A note says the weights are concentrated when this many classes carry more than this share of
#: the total weight (and at least twice as many classes are weighted).
WEIGHT_CONCENTRATION_CLASSES = 2
WEIGHT_CONCENTRATION_SHARE = 0.5

# --- screening and ranking (tromplab.curves) ---------------------------------------------
#: Significance level of the Fisher screen.
DEFAULT_ALPHA = 0.05
#: Ranking criterion -> whether lower is better.
RANK_BY = {"F": False, "aicc": True}

# --- uncertainty and comparison (tromplab.statistics) ------------------------------------
#: How the bootstrap resamples: the residuals of the fit (added to the fitted curve) or whole points.
BOOTSTRAP_METHODS = ("residuals", "cases")
#: Relative margin of practical equivalence of :meth:`SharedFit.conclusion` (and of
#: ``tromplab compare --margin``): estimates within 1 % of each other are equal for practice.
DEFAULT_MARGIN = 0.01

# --- outputs (tromplab.output) -----------------------------------------------------------
#: The products a partition can be read to.
PARTITION_TO = ("fine", "coarse")
#: Above this many experiments, ``figures="auto"`` draws one overview figure instead of one
#: figure per experiment (every fit is still in the fits table).
AUTO_FIGURE_LIMIT = 20
#: What ``figures`` may be: every fit per experiment, the top-ranked one, auto, or none.
FIGURE_CHOICES = ("auto", "all", "best", "none")
#: Formats of the tables (parquet needs pyarrow).
TABLE_FORMATS = ("csv", "parquet")

# --- pulp pressure screens (tromplab.classifiers.pulp) -------------------------------------
#: The coefficients of :class:`~tromplab.classifiers.pulp.PulpScreen` and their defaults (the
#: spec's illustrative values), in the order of its fields: written out so that the command line
#: builds the options of ``tromplab pulp`` without importing the model and numpy (a test checks
#: them against the dataclass).
PULP_SCREEN_DEFAULTS = {"area": 1.0, "open_area": 0.2, "consistency": 10.0, "delay": 0.01, "beta": 2.0, "r": 2.0,
                        "lam": 3.0, "s": 0.5, "phi": 0.0, "tau": 2.0}  # fmt: skip
#: Range of each coefficient, ``(low, high, low_open)``: wide around the spec's illustrative
#: values, and small enough that ``H^r``, ``H^s`` and ``N^tau`` stay finite for the pressure
#: drops and frequencies below (the fit's bounds lie inside them).
PULP_COEFFICIENT_RANGES = {
    "area": (0.0, 1e3, True),
    "open_area": (0.0, 1.0, True),
    "consistency": (0.0, 1e3, True),
    "delay": (0.0, 1e3, False),
    "beta": (0.0, 1e4, True),
    "r": (0.0, 10.0, True),
    "lam": (0.0, 1e4, True),
    "s": (0.0, 10.0, True),
    "phi": (0.0, 1e4, False),
    "tau": (0.0, 5.0, True),
}
#: Pulsation frequencies N (1/s) and applied pressure drops H' the commands take: the
#: search of the best frequency spans 1e-3..1e4 1/s.
PULP_FREQUENCY_RANGE = (1e-3, 1e4)
PULP_PRESSURE_RANGE = (0.0, 1e4)
#: Largest measured productivity a fit takes (units of the inputs, kg/s in the examples): a
#: thousand times the model's rate at the largest coefficients is beyond any screen.
PULP_MAX_PRODUCTIVITY = 1e9

# --- circuit surveys (tromplab.circuit) --------------------------------------------------
#: Relative error of a measured share where the survey gives none (0.05 = 5 %).
DEFAULT_RELATIVE_ERROR = 0.05
#: Absolute error of a share, a fraction of the stream (0.001 = 0.1 percentage point).
DEFAULT_ABSOLUTE_ERROR = 0.001
#: Relative error of a measured solids flow without a standard deviation.
DEFAULT_FLOW_RELATIVE_ERROR = 0.05
#: Standard deviation of a per cent solids without one (percentage points).
DEFAULT_PCT_SOLIDS_SD = 1.0
#: Relative error of a per-class assay (mass share of a component in a class of a stream).
DEFAULT_ASSAY_RELATIVE_ERROR = 0.05
#: Absolute error of an assay, a fraction of the class's solids (0.0005 = 0.05 percentage point).
DEFAULT_ASSAY_ABSOLUTE_ERROR = 0.0005
#: Flow of the first feed when no solids flow is measured: flows are then per 100 of that feed.
CIRCUIT_BASIS = 100.0
#: Formulas ``tromplab circuit --fit`` fits: the nine (ranked) and the extended curves (reported).
CIRCUIT_FIT_FORMULAS = "paper,extended"
#: Where the error model of a survey is evaluated: at the reconciled values (iterated to
#: convergence, the default) or at the measured values.
ERROR_MODEL_POINTS = ("reconciled", "measured")

# --- density partition (tromplab.density) -------------------------------------------------
#: The plain density curves of the registry (``tromplab.density.registry.PLAIN_CURVES``), written
#: out so that the command line builds its parser without the numerical libraries; each has a
#: variant with limits, ``<id>_limits`` (a test checks both against the registry).
PLAIN_DENSITY_CURVES = ("normal", "logistic", "gompertz")
