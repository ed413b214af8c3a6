"""A session of photos -> the room's floor plan, and "find me" on it: photos of one spot
(``spot``), placement of blocks of photos (``fuse`` scored by ``evidence``), joint
refinement (``adjust`` over ``problem``), wall lines and what they are (``walls``,
``wall_kinds``), the outline (``polygon``), the plan (``floorplan``), how well a pose is
pinned (``pose``), and a new photo found on a plan (``find_spot``, ``relocalise``); the
session pipeline is ``session``. Imports ``geometry``, ``single`` and ``motion``."""
