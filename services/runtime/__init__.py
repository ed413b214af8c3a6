"""The service runtime: the bus (keys, configuration, reliable puts), the ``Handler`` API of a
service's pure logic, ``Service``/``Group`` that run handlers on a Zenoh session, and the
registry of services with their command-line options."""

from .service import Counters, Group, Service  # noqa: F401
