"""Find Me core: camera geometry, room hypotheses and synthetic test scenes."""
