from schemas.v1 import common_pb2 as _common_pb2
from google.protobuf.internal import containers as _containers
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class Scene(_message.Message):
    __slots__ = ("schema", "session", "index", "rank", "camera", "camera_height_m", "camera_height_sigma_m", "metric", "polyline", "time_ns", "lines")
    SCHEMA_FIELD_NUMBER: _ClassVar[int]
    SESSION_FIELD_NUMBER: _ClassVar[int]
    INDEX_FIELD_NUMBER: _ClassVar[int]
    RANK_FIELD_NUMBER: _ClassVar[int]
    CAMERA_FIELD_NUMBER: _ClassVar[int]
    CAMERA_HEIGHT_M_FIELD_NUMBER: _ClassVar[int]
    CAMERA_HEIGHT_SIGMA_M_FIELD_NUMBER: _ClassVar[int]
    METRIC_FIELD_NUMBER: _ClassVar[int]
    POLYLINE_FIELD_NUMBER: _ClassVar[int]
    TIME_NS_FIELD_NUMBER: _ClassVar[int]
    LINES_FIELD_NUMBER: _ClassVar[int]
    schema: str
    session: str
    index: int
    rank: int
    camera: _common_pb2.Camera
    camera_height_m: float
    camera_height_sigma_m: float
    metric: bool
    polyline: _common_pb2.Polyline
    time_ns: int
    lines: _containers.RepeatedScalarFieldContainer[float]
    def __init__(self, schema: _Optional[str] = ..., session: _Optional[str] = ..., index: _Optional[int] = ..., rank: _Optional[int] = ..., camera: _Optional[_Union[_common_pb2.Camera, _Mapping]] = ..., camera_height_m: _Optional[float] = ..., camera_height_sigma_m: _Optional[float] = ..., metric: _Optional[bool] = ..., polyline: _Optional[_Union[_common_pb2.Polyline, _Mapping]] = ..., time_ns: _Optional[int] = ..., lines: _Optional[_Iterable[float]] = ...) -> None: ...
