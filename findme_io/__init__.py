"""Adapters between the pure core (``findme_core``) and the outside world, used by both the
services and the command line: image bytes and files (``imageio``), bus messages <-> core
objects (``convert``), and Rerun views (``rerun_views``). Nothing here knows about Zenoh."""
