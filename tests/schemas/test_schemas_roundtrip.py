"""Every bus message type survives encode -> bytes -> decode unchanged."""

from __future__ import annotations

import pytest
from google.protobuf.descriptor import FieldDescriptor

import schemas as S


def test_roundtrip(sample):
    data = S.encode(sample)
    assert isinstance(data, bytes) and data
    back = S.decode(type(sample), data)
    assert back == sample
    assert back.schema == sample.DESCRIPTOR.full_name
    assert S.encode(back) == data  # deterministic (map fields in key order)
    assert S.decode_any(data) == sample
    assert S.schema_of(data) == sample.DESCRIPTOR.full_name


def test_roundtrip_accepts_bytes_like(sample):
    data = S.encode(sample)
    assert S.decode(type(sample), bytearray(data)) == sample
    assert S.decode(type(sample), memoryview(data)) == sample


def test_roundtrip_zenoh_zbytes(sample_of):
    zenoh = pytest.importorskip("zenoh")
    msg = sample_of("findme.v1.Frame")
    assert S.decode(S.Frame, zenoh.ZBytes(S.encode(msg))) == msg


@pytest.mark.parametrize("type_name", sorted(S.MESSAGE_TYPES))
def test_every_type_has_a_sample(type_name, sample_of):
    assert sample_of(type_name).DESCRIPTOR.full_name == type_name


def _covered(msg, acc: set[tuple[str, str]]) -> None:
    """Collect (message type, field) pairs holding a non-default value, recursively
    through findme.v1 message types."""
    d = msg.DESCRIPTOR
    for f in d.fields:
        key = (d.full_name, f.name)
        is_repeated = getattr(f, "is_repeated", None)
        repeated = is_repeated if is_repeated is not None else f.label == FieldDescriptor.LABEL_REPEATED
        value = getattr(msg, f.name)
        if f.message_type is not None and f.message_type.GetOptions().map_entry:
            if len(value):
                acc.add(key)
        elif repeated:
            if len(value):
                acc.add(key)
                if f.message_type is not None:
                    for v in value:
                        _covered(v, acc)
        elif f.message_type is not None:
            if msg.HasField(f.name):
                acc.add(key)
                _covered(value, acc)
        elif f.has_presence:
            if msg.HasField(f.name):
                acc.add(key)
        elif value != f.default_value:
            acc.add(key)


def _all_fields(desc, acc: set[tuple[str, str]], seen: set[str]) -> None:
    if desc.full_name in seen or not desc.full_name.startswith("findme.v1."):
        return
    seen.add(desc.full_name)
    for f in desc.fields:
        acc.add((desc.full_name, f.name))
        if f.message_type is not None and not f.message_type.GetOptions().map_entry:
            _all_fields(f.message_type, acc, seen)


def test_samples_set_every_field(samples):
    """Round-trip samples exercise every field of every type (non-default values), so a
    field added to a .proto without a sample fails here."""
    covered: set[tuple[str, str]] = set()
    for m in samples.values():
        _covered(m, covered)
    wanted: set[tuple[str, str]] = set()
    seen: set[str] = set()
    for cls in S.MESSAGE_TYPES.values():
        _all_fields(cls.DESCRIPTOR, wanted, seen)
    assert sorted(wanted - covered) == []


def test_unknown_fields_are_accepted(sample_of):
    """Forward compatibility: a newer v1 producer may add fields."""
    msg = sample_of("findme.v1.Selection")
    extra = b"\xf8\x06\x2a"  # field 111, varint 42
    back = S.decode(S.Selection, S.encode(msg) + extra)
    back.DiscardUnknownFields()
    assert back == msg
