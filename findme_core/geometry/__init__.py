"""What every stage stands on: the pinhole camera and its level frame (``camera``), planar
motion algebra (``planar``), uncertainty of points (``uncertainty``), where a camera and
gravity came from (``provenance``), the room's orientation (``orientation``), the Manhattan
frame (``manhattan``), robust estimation primitives (``robust``) and a layout's scan by
azimuth (``scan``). Imports nothing of the later stages."""
