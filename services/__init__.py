"""Find Me services on a Zenoh bus, in four kinds:

* ``runtime``: the bus, the ``Handler`` API, ``Service``/``Group`` that run handlers, the registry;
* ``pipeline``: capture, hypotheses, selection, measurement, odometry;
* ``recording``: the recorder (MCAP), its reader/recovery, Foxglove views, the Rerun viewer;
* ``web``: the gateway serving the phone page.

Each service is a thin adapter around a pure handler (``handler.on_message``) that tests
drive without the bus.
"""
