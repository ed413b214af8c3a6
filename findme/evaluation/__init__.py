"""``findme eval``'s machinery: run over a dataset in the findme-eval layout and write predictions in
the format ``shared/eval/score.py`` reads.

Only inputs are used: the image, ``intrinsics``, ``gravity_cam``, ``camera_height_m`` and the
query pixels (``px`` of ``floor_points`` / ``wall_points`` / ``nonfloor_points``); of a pair
only its two view ids (``a``, ``b``): the motion comes from the two views' images and inputs
(rank-1 hypothesis of each chosen, the next ranks as candidate layouts). The result is the same on a copy of the dataset with its ground
truth removed.

A view's ``gravity_cam`` (exact: from the panorama, the depth's floor plane) is taken as it
is, with a 1-sigma of ``--gravity-sigma`` degrees (default
``provenance.INPUT_GRAVITY_SIGMA_DEG``) for the 3D sigmas. ``--gravity-refine`` does what the
services do with a phone's gravity: combine it with the photo's vanishing directions near it
(``gravity_fusion``). ``--gravity-noise DEG`` simulates a phone's sensor error: every view's
gravity is tilted by a random N(0, DEG) in pitch and in roll, seeded by the view's id.
``--no-gravity`` withholds every view's ``gravity_cam``: gravity then comes from the image
(vanishing directions) or is assumed level, as for a photo without sensors.
``--declared-surface`` locates each query point on the surface a user who tapped it would say
(``views.declared_surfaces``: floor and wall points on theirs, TUM's non-floor points on a wall
where their surface is vertical; ``Scene.locate``'s ``surfaces``). Pairs
take the gravity their views end with, as the services do. Each view's prediction says which
gravity it used (``gravity_cam``), where it came from (``gravity_source``: input,
input+image, image or level), its 1-sigma (``gravity_sigma_deg``) and the 1-sigma of every 3D
point (``<kind>_sigma_m``, metres, with its parts ``<kind>_sigma_parts_m``) and the surface it
was put on (``<kind>_surface``: floor, wall, or top when said), so the estimate can be scored against the dataset's
gravity and the sigmas against the errors (``tools/gravity_report.py``).

Modules: ``views`` (a view's inputs and prediction, ``GravityInput``), ``pairs`` (a pair's
motion), ``rooms`` (a room set's plan), ``dataset`` (the whole dataset into predictions
files). The command line is ``findme.cli.evaluate``.
"""
