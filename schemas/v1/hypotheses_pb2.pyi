from schemas.v1 import common_pb2 as _common_pb2
from google.protobuf.internal import containers as _containers
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class Hypothesis(_message.Message):
    __slots__ = ("rank", "score", "support", "polyline")
    RANK_FIELD_NUMBER: _ClassVar[int]
    SCORE_FIELD_NUMBER: _ClassVar[int]
    SUPPORT_FIELD_NUMBER: _ClassVar[int]
    POLYLINE_FIELD_NUMBER: _ClassVar[int]
    rank: int
    score: float
    support: float
    polyline: _common_pb2.Polyline
    def __init__(self, rank: _Optional[int] = ..., score: _Optional[float] = ..., support: _Optional[float] = ..., polyline: _Optional[_Union[_common_pb2.Polyline, _Mapping]] = ...) -> None: ...

class FrameHeight(_message.Message):
    __slots__ = ("camera_height_m", "camera_height_sigma_m")
    CAMERA_HEIGHT_M_FIELD_NUMBER: _ClassVar[int]
    CAMERA_HEIGHT_SIGMA_M_FIELD_NUMBER: _ClassVar[int]
    camera_height_m: float
    camera_height_sigma_m: float
    def __init__(self, camera_height_m: _Optional[float] = ..., camera_height_sigma_m: _Optional[float] = ...) -> None: ...

class HypothesisSet(_message.Message):
    __slots__ = ("schema", "session", "index", "width", "height", "hypotheses", "reason", "timing_ms", "method", "camera", "lines", "frame_height")
    class TimingMsEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: float
        def __init__(self, key: _Optional[str] = ..., value: _Optional[float] = ...) -> None: ...
    SCHEMA_FIELD_NUMBER: _ClassVar[int]
    SESSION_FIELD_NUMBER: _ClassVar[int]
    INDEX_FIELD_NUMBER: _ClassVar[int]
    WIDTH_FIELD_NUMBER: _ClassVar[int]
    HEIGHT_FIELD_NUMBER: _ClassVar[int]
    HYPOTHESES_FIELD_NUMBER: _ClassVar[int]
    REASON_FIELD_NUMBER: _ClassVar[int]
    TIMING_MS_FIELD_NUMBER: _ClassVar[int]
    METHOD_FIELD_NUMBER: _ClassVar[int]
    CAMERA_FIELD_NUMBER: _ClassVar[int]
    LINES_FIELD_NUMBER: _ClassVar[int]
    FRAME_HEIGHT_FIELD_NUMBER: _ClassVar[int]
    schema: str
    session: str
    index: int
    width: int
    height: int
    hypotheses: _containers.RepeatedCompositeFieldContainer[Hypothesis]
    reason: str
    timing_ms: _containers.ScalarMap[str, float]
    method: str
    camera: _common_pb2.Camera
    lines: _containers.RepeatedScalarFieldContainer[float]
    frame_height: FrameHeight
    def __init__(self, schema: _Optional[str] = ..., session: _Optional[str] = ..., index: _Optional[int] = ..., width: _Optional[int] = ..., height: _Optional[int] = ..., hypotheses: _Optional[_Iterable[_Union[Hypothesis, _Mapping]]] = ..., reason: _Optional[str] = ..., timing_ms: _Optional[_Mapping[str, float]] = ..., method: _Optional[str] = ..., camera: _Optional[_Union[_common_pb2.Camera, _Mapping]] = ..., lines: _Optional[_Iterable[float]] = ..., frame_height: _Optional[_Union[FrameHeight, _Mapping]] = ...) -> None: ...
