from google.protobuf.internal import containers as _containers
from google.protobuf.internal import enum_type_wrapper as _enum_type_wrapper
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class SegKind(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    SEG_KIND_WALL: _ClassVar[SegKind]
    SEG_KIND_STEP: _ClassVar[SegKind]
    SEG_KIND_OPEN: _ClassVar[SegKind]
    SEG_KIND_NONE: _ClassVar[SegKind]
SEG_KIND_WALL: SegKind
SEG_KIND_STEP: SegKind
SEG_KIND_OPEN: SegKind
SEG_KIND_NONE: SegKind

class Envelope(_message.Message):
    __slots__ = ("schema",)
    SCHEMA_FIELD_NUMBER: _ClassVar[int]
    schema: str
    def __init__(self, schema: _Optional[str] = ...) -> None: ...

class Pixel(_message.Message):
    __slots__ = ("u", "v")
    U_FIELD_NUMBER: _ClassVar[int]
    V_FIELD_NUMBER: _ClassVar[int]
    u: float
    v: float
    def __init__(self, u: _Optional[float] = ..., v: _Optional[float] = ...) -> None: ...

class Vec3(_message.Message):
    __slots__ = ("x", "y", "z")
    X_FIELD_NUMBER: _ClassVar[int]
    Y_FIELD_NUMBER: _ClassVar[int]
    Z_FIELD_NUMBER: _ClassVar[int]
    x: float
    y: float
    z: float
    def __init__(self, x: _Optional[float] = ..., y: _Optional[float] = ..., z: _Optional[float] = ...) -> None: ...

class Intrinsics(_message.Message):
    __slots__ = ("fx", "fy", "cx", "cy", "width", "height")
    FX_FIELD_NUMBER: _ClassVar[int]
    FY_FIELD_NUMBER: _ClassVar[int]
    CX_FIELD_NUMBER: _ClassVar[int]
    CY_FIELD_NUMBER: _ClassVar[int]
    WIDTH_FIELD_NUMBER: _ClassVar[int]
    HEIGHT_FIELD_NUMBER: _ClassVar[int]
    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    def __init__(self, fx: _Optional[float] = ..., fy: _Optional[float] = ..., cx: _Optional[float] = ..., cy: _Optional[float] = ..., width: _Optional[int] = ..., height: _Optional[int] = ...) -> None: ...

class Camera(_message.Message):
    __slots__ = ("intrinsics", "gravity", "lens_source", "gravity_source", "gravity_sigma_rad", "gravity_cov_rad2", "gravity_alternatives", "gravity_fit_cov_rad2")
    INTRINSICS_FIELD_NUMBER: _ClassVar[int]
    GRAVITY_FIELD_NUMBER: _ClassVar[int]
    LENS_SOURCE_FIELD_NUMBER: _ClassVar[int]
    GRAVITY_SOURCE_FIELD_NUMBER: _ClassVar[int]
    GRAVITY_SIGMA_RAD_FIELD_NUMBER: _ClassVar[int]
    GRAVITY_COV_RAD2_FIELD_NUMBER: _ClassVar[int]
    GRAVITY_ALTERNATIVES_FIELD_NUMBER: _ClassVar[int]
    GRAVITY_FIT_COV_RAD2_FIELD_NUMBER: _ClassVar[int]
    intrinsics: Intrinsics
    gravity: Vec3
    lens_source: str
    gravity_source: str
    gravity_sigma_rad: float
    gravity_cov_rad2: _containers.RepeatedScalarFieldContainer[float]
    gravity_alternatives: _containers.RepeatedCompositeFieldContainer[GravityAlternative]
    gravity_fit_cov_rad2: _containers.RepeatedScalarFieldContainer[float]
    def __init__(self, intrinsics: _Optional[_Union[Intrinsics, _Mapping]] = ..., gravity: _Optional[_Union[Vec3, _Mapping]] = ..., lens_source: _Optional[str] = ..., gravity_source: _Optional[str] = ..., gravity_sigma_rad: _Optional[float] = ..., gravity_cov_rad2: _Optional[_Iterable[float]] = ..., gravity_alternatives: _Optional[_Iterable[_Union[GravityAlternative, _Mapping]]] = ..., gravity_fit_cov_rad2: _Optional[_Iterable[float]] = ...) -> None: ...

class GravityAlternative(_message.Message):
    __slots__ = ("gravity", "ratio")
    GRAVITY_FIELD_NUMBER: _ClassVar[int]
    RATIO_FIELD_NUMBER: _ClassVar[int]
    gravity: Vec3
    ratio: float
    def __init__(self, gravity: _Optional[_Union[Vec3, _Mapping]] = ..., ratio: _Optional[float] = ...) -> None: ...

class Polyline(_message.Message):
    __slots__ = ("points", "kinds")
    POINTS_FIELD_NUMBER: _ClassVar[int]
    KINDS_FIELD_NUMBER: _ClassVar[int]
    points: _containers.RepeatedCompositeFieldContainer[Pixel]
    kinds: _containers.RepeatedScalarFieldContainer[SegKind]
    def __init__(self, points: _Optional[_Iterable[_Union[Pixel, _Mapping]]] = ..., kinds: _Optional[_Iterable[_Union[SegKind, str]]] = ...) -> None: ...
