from google.protobuf.internal import containers as _containers
from google.protobuf.internal import enum_type_wrapper as _enum_type_wrapper
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class WallKind(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    WALL_KIND_UNSPECIFIED: _ClassVar[WallKind]
    WALL_KIND_WALL: _ClassVar[WallKind]
    WALL_KIND_OPENING: _ClassVar[WallKind]
    WALL_KIND_MISSING: _ClassVar[WallKind]

class PlanPhotoStatus(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    PLAN_PHOTO_STATUS_UNSPECIFIED: _ClassVar[PlanPhotoStatus]
    PLAN_PHOTO_STATUS_PLACED: _ClassVar[PlanPhotoStatus]
    PLAN_PHOTO_STATUS_NOT_PLACED: _ClassVar[PlanPhotoStatus]
    PLAN_PHOTO_STATUS_LEFT_OUT: _ClassVar[PlanPhotoStatus]
WALL_KIND_UNSPECIFIED: WallKind
WALL_KIND_WALL: WallKind
WALL_KIND_OPENING: WallKind
WALL_KIND_MISSING: WallKind
PLAN_PHOTO_STATUS_UNSPECIFIED: PlanPhotoStatus
PLAN_PHOTO_STATUS_PLACED: PlanPhotoStatus
PLAN_PHOTO_STATUS_NOT_PLACED: PlanPhotoStatus
PLAN_PHOTO_STATUS_LEFT_OUT: PlanPhotoStatus

class PlanPoint(_message.Message):
    __slots__ = ("x_m", "z_m", "sigma_x_m", "sigma_z_m")
    X_M_FIELD_NUMBER: _ClassVar[int]
    Z_M_FIELD_NUMBER: _ClassVar[int]
    SIGMA_X_M_FIELD_NUMBER: _ClassVar[int]
    SIGMA_Z_M_FIELD_NUMBER: _ClassVar[int]
    x_m: float
    z_m: float
    sigma_x_m: float
    sigma_z_m: float
    def __init__(self, x_m: _Optional[float] = ..., z_m: _Optional[float] = ..., sigma_x_m: _Optional[float] = ..., sigma_z_m: _Optional[float] = ...) -> None: ...

class PlanOpening(_message.Message):
    __slots__ = ("from_m", "to_m")
    FROM_M_FIELD_NUMBER: _ClassVar[int]
    TO_M_FIELD_NUMBER: _ClassVar[int]
    from_m: float
    to_m: float
    def __init__(self, from_m: _Optional[float] = ..., to_m: _Optional[float] = ...) -> None: ...

class PlanWall(_message.Message):
    __slots__ = ("a", "b", "length_m", "sigma_m", "kind", "openings")
    A_FIELD_NUMBER: _ClassVar[int]
    B_FIELD_NUMBER: _ClassVar[int]
    LENGTH_M_FIELD_NUMBER: _ClassVar[int]
    SIGMA_M_FIELD_NUMBER: _ClassVar[int]
    KIND_FIELD_NUMBER: _ClassVar[int]
    OPENINGS_FIELD_NUMBER: _ClassVar[int]
    a: PlanPoint
    b: PlanPoint
    length_m: float
    sigma_m: float
    kind: WallKind
    openings: _containers.RepeatedCompositeFieldContainer[PlanOpening]
    def __init__(self, a: _Optional[_Union[PlanPoint, _Mapping]] = ..., b: _Optional[_Union[PlanPoint, _Mapping]] = ..., length_m: _Optional[float] = ..., sigma_m: _Optional[float] = ..., kind: _Optional[_Union[WallKind, str]] = ..., openings: _Optional[_Iterable[_Union[PlanOpening, _Mapping]]] = ...) -> None: ...

class PlanPhoto(_message.Message):
    __slots__ = ("index", "status", "x_m", "z_m", "yaw_rad", "sigma_x_m", "sigma_z_m", "sigma_yaw_rad", "spot", "ambiguity", "reason")
    INDEX_FIELD_NUMBER: _ClassVar[int]
    STATUS_FIELD_NUMBER: _ClassVar[int]
    X_M_FIELD_NUMBER: _ClassVar[int]
    Z_M_FIELD_NUMBER: _ClassVar[int]
    YAW_RAD_FIELD_NUMBER: _ClassVar[int]
    SIGMA_X_M_FIELD_NUMBER: _ClassVar[int]
    SIGMA_Z_M_FIELD_NUMBER: _ClassVar[int]
    SIGMA_YAW_RAD_FIELD_NUMBER: _ClassVar[int]
    SPOT_FIELD_NUMBER: _ClassVar[int]
    AMBIGUITY_FIELD_NUMBER: _ClassVar[int]
    REASON_FIELD_NUMBER: _ClassVar[int]
    index: int
    status: PlanPhotoStatus
    x_m: float
    z_m: float
    yaw_rad: float
    sigma_x_m: float
    sigma_z_m: float
    sigma_yaw_rad: float
    spot: int
    ambiguity: float
    reason: str
    def __init__(self, index: _Optional[int] = ..., status: _Optional[_Union[PlanPhotoStatus, str]] = ..., x_m: _Optional[float] = ..., z_m: _Optional[float] = ..., yaw_rad: _Optional[float] = ..., sigma_x_m: _Optional[float] = ..., sigma_z_m: _Optional[float] = ..., sigma_yaw_rad: _Optional[float] = ..., spot: _Optional[int] = ..., ambiguity: _Optional[float] = ..., reason: _Optional[str] = ...) -> None: ...

class Plan(_message.Message):
    __slots__ = ("schema", "session", "up_to_index", "photos", "origin_index", "metric", "camera_height_m", "polygon", "walls", "area_m2", "closed", "manhattan", "poses", "reason", "time_ns", "timing_ms")
    class TimingMsEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: float
        def __init__(self, key: _Optional[str] = ..., value: _Optional[float] = ...) -> None: ...
    SCHEMA_FIELD_NUMBER: _ClassVar[int]
    SESSION_FIELD_NUMBER: _ClassVar[int]
    UP_TO_INDEX_FIELD_NUMBER: _ClassVar[int]
    PHOTOS_FIELD_NUMBER: _ClassVar[int]
    ORIGIN_INDEX_FIELD_NUMBER: _ClassVar[int]
    METRIC_FIELD_NUMBER: _ClassVar[int]
    CAMERA_HEIGHT_M_FIELD_NUMBER: _ClassVar[int]
    POLYGON_FIELD_NUMBER: _ClassVar[int]
    WALLS_FIELD_NUMBER: _ClassVar[int]
    AREA_M2_FIELD_NUMBER: _ClassVar[int]
    CLOSED_FIELD_NUMBER: _ClassVar[int]
    MANHATTAN_FIELD_NUMBER: _ClassVar[int]
    POSES_FIELD_NUMBER: _ClassVar[int]
    REASON_FIELD_NUMBER: _ClassVar[int]
    TIME_NS_FIELD_NUMBER: _ClassVar[int]
    TIMING_MS_FIELD_NUMBER: _ClassVar[int]
    schema: str
    session: str
    up_to_index: int
    photos: int
    origin_index: int
    metric: bool
    camera_height_m: float
    polygon: _containers.RepeatedCompositeFieldContainer[PlanPoint]
    walls: _containers.RepeatedCompositeFieldContainer[PlanWall]
    area_m2: float
    closed: bool
    manhattan: bool
    poses: _containers.RepeatedCompositeFieldContainer[PlanPhoto]
    reason: str
    time_ns: int
    timing_ms: _containers.ScalarMap[str, float]
    def __init__(self, schema: _Optional[str] = ..., session: _Optional[str] = ..., up_to_index: _Optional[int] = ..., photos: _Optional[int] = ..., origin_index: _Optional[int] = ..., metric: _Optional[bool] = ..., camera_height_m: _Optional[float] = ..., polygon: _Optional[_Iterable[_Union[PlanPoint, _Mapping]]] = ..., walls: _Optional[_Iterable[_Union[PlanWall, _Mapping]]] = ..., area_m2: _Optional[float] = ..., closed: _Optional[bool] = ..., manhattan: _Optional[bool] = ..., poses: _Optional[_Iterable[_Union[PlanPhoto, _Mapping]]] = ..., reason: _Optional[str] = ..., time_ns: _Optional[int] = ..., timing_ms: _Optional[_Mapping[str, float]] = ...) -> None: ...
