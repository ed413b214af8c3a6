"""The layout of a Find Me recording (MCAP): its channels, their topics and metadata, and
the rule that gives a recorded message its bus key back.

* **Bus channels**, one per key *kind*: topic ``findme/<session>/<kind>`` (``frame``,
  ``hypotheses``, ``selection``, ``scene``, ``motion``, ``pose``, ``trajectory``, ``error``,
  ``measured``, ``plan``), protobuf encoding, the message's own schema (a FileDescriptorSet, so any
  MCAP reader decodes it without our code), the payload bytes exactly as they were on the bus.
  The rest of the key follows from the payload (``frame/<n>`` is ``Frame.index``,
  ``motion/<a>/<b>`` is ``Motion.index_a/index_b``, ...: ``key_of``, from ``KEY_RULES``);
  the writer checks that rule on every message, and a message whose key does not follow
  from it (malformed, foreign, an unknown kind) goes on a channel named by its exact key
  instead (metadata ``findme.channel = bus-exact``). Either way ``findme replay`` puts every
  message back on the key it came from. One channel per kind rather than per key keeps a
  video session within MCAP's 65535 channels and gives Foxglove one topic per stream.
* **View channels**, ``findme/<session>/foxglove/<name>`` (``view_topic``; metadata
  ``findme.channel = view``; replay skips them): what ``services.foxglove_view`` derives.

recordings/README.md has the full table. Log time of a message = when the recorder received
it (ns since the epoch); publish time the same.
"""

from __future__ import annotations

from google.protobuf.message import DecodeError

import schemas
from findme_core.errors import FindmeError

from ..runtime import bus
from ..runtime.authority import KEY_RULES  # message type -> (key kind, index fields)

VERSION = "findme-recorder/1"

# channel metadata
CHANNEL = "findme.channel"     # "bus" (key from payload), "bus-exact" (topic = key), "view"
KIND = "findme.kind"

KIND_TYPES = {kind: name for name, (kind, _) in KEY_RULES.items()}

MCAP_MAGIC = b"\x89MCAP0\r\n"


def key_of(session: str, msg) -> str | None:
    """The bus key a message of a known kind belongs on (``findme/<session>/<kind>/...``)."""
    rule = KEY_RULES.get(msg.DESCRIPTOR.full_name)
    if rule is None:
        return None
    kind, fields = rule
    return "/".join([bus.ROOT, session, kind, *(str(getattr(msg, f)) for f in fields)])


def kind_topic(session: str, kind: str) -> str:
    return f"{bus.ROOT}/{session}/{kind}"


def view_topic(session: str, name: str) -> str:
    return f"{bus.ROOT}/{session}/foxglove/{name}"


def parse(payload: bytes):
    """(message or None, type name or ""): a Find Me message parsed without validation."""
    try:
        name = schemas.schema_of(payload)
    except FindmeError:
        return None, ""
    cls = schemas.MESSAGE_TYPES.get(name)
    if cls is None:
        return None, ""
    try:
        return cls.FromString(payload), name
    except DecodeError:
        return None, ""

