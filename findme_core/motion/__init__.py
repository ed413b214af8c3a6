"""Two photos -> planar motion -> trajectory: features and matches (``features``), matched
pixels lifted to 3D (``lifting``), two layouts registered (``register``), the estimators
(``methods`` dispatches: ``estimator`` with ``fit``, ``alternatives``, ``one_sided``,
``photometric``; ``feature_motion``; ``baselines``, the paper's eqs. 5-8; shared ``model``),
the pipeline for a pair of photos (``pair``) and the chained trajectory (``trajectory``).
Imports ``geometry`` and ``single``."""
