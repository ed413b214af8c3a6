from schemas.v1 import common_pb2 as _common_pb2
from google.protobuf.internal import containers as _containers
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class Motion(_message.Message):
    __slots__ = ("schema", "session", "index_a", "index_b", "x_m", "z_m", "yaw_rad", "sigma_x_m", "sigma_z_m", "sigma_yaw_rad", "inliers", "matches", "method", "error", "time_ns", "score", "scale_points", "layout", "alternatives", "appearance", "appearance_samples", "gravity")
    SCHEMA_FIELD_NUMBER: _ClassVar[int]
    SESSION_FIELD_NUMBER: _ClassVar[int]
    INDEX_A_FIELD_NUMBER: _ClassVar[int]
    INDEX_B_FIELD_NUMBER: _ClassVar[int]
    X_M_FIELD_NUMBER: _ClassVar[int]
    Z_M_FIELD_NUMBER: _ClassVar[int]
    YAW_RAD_FIELD_NUMBER: _ClassVar[int]
    SIGMA_X_M_FIELD_NUMBER: _ClassVar[int]
    SIGMA_Z_M_FIELD_NUMBER: _ClassVar[int]
    SIGMA_YAW_RAD_FIELD_NUMBER: _ClassVar[int]
    INLIERS_FIELD_NUMBER: _ClassVar[int]
    MATCHES_FIELD_NUMBER: _ClassVar[int]
    METHOD_FIELD_NUMBER: _ClassVar[int]
    ERROR_FIELD_NUMBER: _ClassVar[int]
    TIME_NS_FIELD_NUMBER: _ClassVar[int]
    SCORE_FIELD_NUMBER: _ClassVar[int]
    SCALE_POINTS_FIELD_NUMBER: _ClassVar[int]
    LAYOUT_FIELD_NUMBER: _ClassVar[int]
    ALTERNATIVES_FIELD_NUMBER: _ClassVar[int]
    APPEARANCE_FIELD_NUMBER: _ClassVar[int]
    APPEARANCE_SAMPLES_FIELD_NUMBER: _ClassVar[int]
    GRAVITY_FIELD_NUMBER: _ClassVar[int]
    schema: str
    session: str
    index_a: int
    index_b: int
    x_m: float
    z_m: float
    yaw_rad: float
    sigma_x_m: float
    sigma_z_m: float
    sigma_yaw_rad: float
    inliers: int
    matches: int
    method: str
    error: str
    time_ns: int
    score: float
    scale_points: int
    layout: MotionLayout
    alternatives: _containers.RepeatedCompositeFieldContainer[MotionAlternative]
    appearance: float
    appearance_samples: int
    gravity: MotionGravity
    def __init__(self, schema: _Optional[str] = ..., session: _Optional[str] = ..., index_a: _Optional[int] = ..., index_b: _Optional[int] = ..., x_m: _Optional[float] = ..., z_m: _Optional[float] = ..., yaw_rad: _Optional[float] = ..., sigma_x_m: _Optional[float] = ..., sigma_z_m: _Optional[float] = ..., sigma_yaw_rad: _Optional[float] = ..., inliers: _Optional[int] = ..., matches: _Optional[int] = ..., method: _Optional[str] = ..., error: _Optional[str] = ..., time_ns: _Optional[int] = ..., score: _Optional[float] = ..., scale_points: _Optional[int] = ..., layout: _Optional[_Union[MotionLayout, _Mapping]] = ..., alternatives: _Optional[_Iterable[_Union[MotionAlternative, _Mapping]]] = ..., appearance: _Optional[float] = ..., appearance_samples: _Optional[int] = ..., gravity: _Optional[_Union[MotionGravity, _Mapping]] = ...) -> None: ...

class MotionGravity(_message.Message):
    __slots__ = ("status", "angle_rad", "sigma_a_rad", "sigma_b_rad", "reason", "gravity_a", "gravity_b")
    STATUS_FIELD_NUMBER: _ClassVar[int]
    ANGLE_RAD_FIELD_NUMBER: _ClassVar[int]
    SIGMA_A_RAD_FIELD_NUMBER: _ClassVar[int]
    SIGMA_B_RAD_FIELD_NUMBER: _ClassVar[int]
    REASON_FIELD_NUMBER: _ClassVar[int]
    GRAVITY_A_FIELD_NUMBER: _ClassVar[int]
    GRAVITY_B_FIELD_NUMBER: _ClassVar[int]
    status: str
    angle_rad: float
    sigma_a_rad: float
    sigma_b_rad: float
    reason: str
    gravity_a: _common_pb2.Vec3
    gravity_b: _common_pb2.Vec3
    def __init__(self, status: _Optional[str] = ..., angle_rad: _Optional[float] = ..., sigma_a_rad: _Optional[float] = ..., sigma_b_rad: _Optional[float] = ..., reason: _Optional[str] = ..., gravity_a: _Optional[_Union[_common_pb2.Vec3, _Mapping]] = ..., gravity_b: _Optional[_Union[_common_pb2.Vec3, _Mapping]] = ...) -> None: ...

class MotionLayout(_message.Message):
    __slots__ = ("rank_a", "rank_b", "samples", "violations", "rms_m", "walls", "corners")
    RANK_A_FIELD_NUMBER: _ClassVar[int]
    RANK_B_FIELD_NUMBER: _ClassVar[int]
    SAMPLES_FIELD_NUMBER: _ClassVar[int]
    VIOLATIONS_FIELD_NUMBER: _ClassVar[int]
    RMS_M_FIELD_NUMBER: _ClassVar[int]
    WALLS_FIELD_NUMBER: _ClassVar[int]
    CORNERS_FIELD_NUMBER: _ClassVar[int]
    rank_a: int
    rank_b: int
    samples: int
    violations: int
    rms_m: float
    walls: _containers.RepeatedCompositeFieldContainer[IndexPair]
    corners: _containers.RepeatedCompositeFieldContainer[IndexPair]
    def __init__(self, rank_a: _Optional[int] = ..., rank_b: _Optional[int] = ..., samples: _Optional[int] = ..., violations: _Optional[int] = ..., rms_m: _Optional[float] = ..., walls: _Optional[_Iterable[_Union[IndexPair, _Mapping]]] = ..., corners: _Optional[_Iterable[_Union[IndexPair, _Mapping]]] = ...) -> None: ...

class IndexPair(_message.Message):
    __slots__ = ("a", "b")
    A_FIELD_NUMBER: _ClassVar[int]
    B_FIELD_NUMBER: _ClassVar[int]
    a: int
    b: int
    def __init__(self, a: _Optional[int] = ..., b: _Optional[int] = ...) -> None: ...

class MotionAlternative(_message.Message):
    __slots__ = ("x_m", "z_m", "yaw_rad", "sigma_x_m", "sigma_z_m", "sigma_yaw_rad", "inliers", "score")
    X_M_FIELD_NUMBER: _ClassVar[int]
    Z_M_FIELD_NUMBER: _ClassVar[int]
    YAW_RAD_FIELD_NUMBER: _ClassVar[int]
    SIGMA_X_M_FIELD_NUMBER: _ClassVar[int]
    SIGMA_Z_M_FIELD_NUMBER: _ClassVar[int]
    SIGMA_YAW_RAD_FIELD_NUMBER: _ClassVar[int]
    INLIERS_FIELD_NUMBER: _ClassVar[int]
    SCORE_FIELD_NUMBER: _ClassVar[int]
    x_m: float
    z_m: float
    yaw_rad: float
    sigma_x_m: float
    sigma_z_m: float
    sigma_yaw_rad: float
    inliers: int
    score: float
    def __init__(self, x_m: _Optional[float] = ..., z_m: _Optional[float] = ..., yaw_rad: _Optional[float] = ..., sigma_x_m: _Optional[float] = ..., sigma_z_m: _Optional[float] = ..., sigma_yaw_rad: _Optional[float] = ..., inliers: _Optional[int] = ..., score: _Optional[float] = ...) -> None: ...

class Pose(_message.Message):
    __slots__ = ("schema", "session", "index", "x_m", "z_m", "yaw_rad", "time_ns", "sigma_x_m", "sigma_z_m", "sigma_yaw_rad")
    SCHEMA_FIELD_NUMBER: _ClassVar[int]
    SESSION_FIELD_NUMBER: _ClassVar[int]
    INDEX_FIELD_NUMBER: _ClassVar[int]
    X_M_FIELD_NUMBER: _ClassVar[int]
    Z_M_FIELD_NUMBER: _ClassVar[int]
    YAW_RAD_FIELD_NUMBER: _ClassVar[int]
    TIME_NS_FIELD_NUMBER: _ClassVar[int]
    SIGMA_X_M_FIELD_NUMBER: _ClassVar[int]
    SIGMA_Z_M_FIELD_NUMBER: _ClassVar[int]
    SIGMA_YAW_RAD_FIELD_NUMBER: _ClassVar[int]
    schema: str
    session: str
    index: int
    x_m: float
    z_m: float
    yaw_rad: float
    time_ns: int
    sigma_x_m: float
    sigma_z_m: float
    sigma_yaw_rad: float
    def __init__(self, schema: _Optional[str] = ..., session: _Optional[str] = ..., index: _Optional[int] = ..., x_m: _Optional[float] = ..., z_m: _Optional[float] = ..., yaw_rad: _Optional[float] = ..., time_ns: _Optional[int] = ..., sigma_x_m: _Optional[float] = ..., sigma_z_m: _Optional[float] = ..., sigma_yaw_rad: _Optional[float] = ...) -> None: ...

class Trajectory(_message.Message):
    __slots__ = ("schema", "session", "poses", "time_ns")
    SCHEMA_FIELD_NUMBER: _ClassVar[int]
    SESSION_FIELD_NUMBER: _ClassVar[int]
    POSES_FIELD_NUMBER: _ClassVar[int]
    TIME_NS_FIELD_NUMBER: _ClassVar[int]
    schema: str
    session: str
    poses: _containers.RepeatedCompositeFieldContainer[Pose]
    time_ns: int
    def __init__(self, schema: _Optional[str] = ..., session: _Optional[str] = ..., poses: _Optional[_Iterable[_Union[Pose, _Mapping]]] = ..., time_ns: _Optional[int] = ...) -> None: ...
