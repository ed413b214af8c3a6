"""Find Me core: the algorithms, pure (numpy and OpenCV in, numbers out; no I/O, clocks or
environment), in the order the data flows:

* ``geometry``: what every stage stands on (camera and level frame, planar motion algebra,
  uncertainty, provenance, robust estimation, the Manhattan frame, room orientation).
* ``single``: one photo -> gravity, ground-wall boundary hypotheses -> its scene (3D of
  floor and wall pixels, paper eqs. 2-4) and its room layout on the floor.
* ``motion``: two photos -> feature matches -> planar camera motion (paper eqs. 5-8 and our
  estimator) -> a trajectory.
* ``plan``: a session of photos -> the room's floor plan, and "find me" on it.
* ``synth``: rendered rooms with exact ground truth, for tests and the bundled example.

Each stage imports only the stages before it (``pyproject.toml``'s import-linter contracts);
``errors`` is the one exception root, shared by all.
"""
