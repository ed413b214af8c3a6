"""One photo -> boundary hypotheses -> scene: line segments (``segments``, ``lines``), gravity
from the image or a sensor refined by it (``vanishing``, ``corners``, ``gravity_fusion``),
the boundary search and its ranking (``support``, ``search``, ``paths``, ``appearance``,
``ranking``, ``refine``, ``counters``, ``hypotheses``, ``paper``, ``methods``, ``photo``),
then the scene of a chosen boundary (``scene``, paper eqs. 2-4) and its layout on the floor
(``layout``). Imports ``geometry`` only."""
