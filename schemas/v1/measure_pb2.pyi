from schemas.v1 import common_pb2 as _common_pb2
from google.protobuf.internal import containers as _containers
from google.protobuf.internal import enum_type_wrapper as _enum_type_wrapper
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class Surface(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    SURFACE_NONE: _ClassVar[Surface]
    SURFACE_FLOOR: _ClassVar[Surface]
    SURFACE_WALL: _ClassVar[Surface]
    SURFACE_TOP: _ClassVar[Surface]
SURFACE_NONE: Surface
SURFACE_FLOOR: Surface
SURFACE_WALL: Surface
SURFACE_TOP: Surface

class MeasureRequest(_message.Message):
    __slots__ = ("schema", "session", "index", "pixels", "said")
    SCHEMA_FIELD_NUMBER: _ClassVar[int]
    SESSION_FIELD_NUMBER: _ClassVar[int]
    INDEX_FIELD_NUMBER: _ClassVar[int]
    PIXELS_FIELD_NUMBER: _ClassVar[int]
    SAID_FIELD_NUMBER: _ClassVar[int]
    schema: str
    session: str
    index: int
    pixels: _containers.RepeatedCompositeFieldContainer[_common_pb2.Pixel]
    said: _containers.RepeatedScalarFieldContainer[Surface]
    def __init__(self, schema: _Optional[str] = ..., session: _Optional[str] = ..., index: _Optional[int] = ..., pixels: _Optional[_Iterable[_Union[_common_pb2.Pixel, _Mapping]]] = ..., said: _Optional[_Iterable[_Union[Surface, str]]] = ...) -> None: ...

class MeasuredPoint(_message.Message):
    __slots__ = ("pixel", "surface", "xyz", "sigma_m", "error", "said", "note")
    PIXEL_FIELD_NUMBER: _ClassVar[int]
    SURFACE_FIELD_NUMBER: _ClassVar[int]
    XYZ_FIELD_NUMBER: _ClassVar[int]
    SIGMA_M_FIELD_NUMBER: _ClassVar[int]
    ERROR_FIELD_NUMBER: _ClassVar[int]
    SAID_FIELD_NUMBER: _ClassVar[int]
    NOTE_FIELD_NUMBER: _ClassVar[int]
    pixel: _common_pb2.Pixel
    surface: Surface
    xyz: _common_pb2.Vec3
    sigma_m: float
    error: str
    said: Surface
    note: str
    def __init__(self, pixel: _Optional[_Union[_common_pb2.Pixel, _Mapping]] = ..., surface: _Optional[_Union[Surface, str]] = ..., xyz: _Optional[_Union[_common_pb2.Vec3, _Mapping]] = ..., sigma_m: _Optional[float] = ..., error: _Optional[str] = ..., said: _Optional[_Union[Surface, str]] = ..., note: _Optional[str] = ...) -> None: ...

class Distance(_message.Message):
    __slots__ = ("a", "b", "distance_m", "sigma_m", "error")
    A_FIELD_NUMBER: _ClassVar[int]
    B_FIELD_NUMBER: _ClassVar[int]
    DISTANCE_M_FIELD_NUMBER: _ClassVar[int]
    SIGMA_M_FIELD_NUMBER: _ClassVar[int]
    ERROR_FIELD_NUMBER: _ClassVar[int]
    a: int
    b: int
    distance_m: float
    sigma_m: float
    error: str
    def __init__(self, a: _Optional[int] = ..., b: _Optional[int] = ..., distance_m: _Optional[float] = ..., sigma_m: _Optional[float] = ..., error: _Optional[str] = ...) -> None: ...

class MeasureReply(_message.Message):
    __slots__ = ("schema", "session", "index", "points", "distances", "error", "rank", "metric")
    SCHEMA_FIELD_NUMBER: _ClassVar[int]
    SESSION_FIELD_NUMBER: _ClassVar[int]
    INDEX_FIELD_NUMBER: _ClassVar[int]
    POINTS_FIELD_NUMBER: _ClassVar[int]
    DISTANCES_FIELD_NUMBER: _ClassVar[int]
    ERROR_FIELD_NUMBER: _ClassVar[int]
    RANK_FIELD_NUMBER: _ClassVar[int]
    METRIC_FIELD_NUMBER: _ClassVar[int]
    schema: str
    session: str
    index: int
    points: _containers.RepeatedCompositeFieldContainer[MeasuredPoint]
    distances: _containers.RepeatedCompositeFieldContainer[Distance]
    error: str
    rank: int
    metric: bool
    def __init__(self, schema: _Optional[str] = ..., session: _Optional[str] = ..., index: _Optional[int] = ..., points: _Optional[_Iterable[_Union[MeasuredPoint, _Mapping]]] = ..., distances: _Optional[_Iterable[_Union[Distance, _Mapping]]] = ..., error: _Optional[str] = ..., rank: _Optional[int] = ..., metric: _Optional[bool] = ...) -> None: ...
