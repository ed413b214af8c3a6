"""Rendered rooms with exact ground truth, for tests and the bundled example: the scene
description (``room``), seeded textures (``textures``), ray casting and shading
(``raycast``) and the photo with its truth (``render``). Imports ``geometry`` only; no
stage imports it."""
