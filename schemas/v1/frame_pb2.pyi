from foxglove_schemas_protobuf import CompressedImage_pb2 as _CompressedImage_pb2
from schemas.v1 import common_pb2 as _common_pb2
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class Frame(_message.Message):
    __slots__ = ("schema", "session", "index", "capture_time_ns", "image", "intrinsics", "hfov_deg", "gravity", "camera_height_m", "camera_height_sigma_m", "device", "gravity_sigma_rad", "heading_rad", "heading_sigma_rad", "heading_ref")
    SCHEMA_FIELD_NUMBER: _ClassVar[int]
    SESSION_FIELD_NUMBER: _ClassVar[int]
    INDEX_FIELD_NUMBER: _ClassVar[int]
    CAPTURE_TIME_NS_FIELD_NUMBER: _ClassVar[int]
    IMAGE_FIELD_NUMBER: _ClassVar[int]
    INTRINSICS_FIELD_NUMBER: _ClassVar[int]
    HFOV_DEG_FIELD_NUMBER: _ClassVar[int]
    GRAVITY_FIELD_NUMBER: _ClassVar[int]
    CAMERA_HEIGHT_M_FIELD_NUMBER: _ClassVar[int]
    CAMERA_HEIGHT_SIGMA_M_FIELD_NUMBER: _ClassVar[int]
    DEVICE_FIELD_NUMBER: _ClassVar[int]
    GRAVITY_SIGMA_RAD_FIELD_NUMBER: _ClassVar[int]
    HEADING_RAD_FIELD_NUMBER: _ClassVar[int]
    HEADING_SIGMA_RAD_FIELD_NUMBER: _ClassVar[int]
    HEADING_REF_FIELD_NUMBER: _ClassVar[int]
    schema: str
    session: str
    index: int
    capture_time_ns: int
    image: _CompressedImage_pb2.CompressedImage
    intrinsics: _common_pb2.Intrinsics
    hfov_deg: float
    gravity: _common_pb2.Vec3
    camera_height_m: float
    camera_height_sigma_m: float
    device: str
    gravity_sigma_rad: float
    heading_rad: float
    heading_sigma_rad: float
    heading_ref: str
    def __init__(self, schema: _Optional[str] = ..., session: _Optional[str] = ..., index: _Optional[int] = ..., capture_time_ns: _Optional[int] = ..., image: _Optional[_Union[_CompressedImage_pb2.CompressedImage, _Mapping]] = ..., intrinsics: _Optional[_Union[_common_pb2.Intrinsics, _Mapping]] = ..., hfov_deg: _Optional[float] = ..., gravity: _Optional[_Union[_common_pb2.Vec3, _Mapping]] = ..., camera_height_m: _Optional[float] = ..., camera_height_sigma_m: _Optional[float] = ..., device: _Optional[str] = ..., gravity_sigma_rad: _Optional[float] = ..., heading_rad: _Optional[float] = ..., heading_sigma_rad: _Optional[float] = ..., heading_ref: _Optional[str] = ...) -> None: ...
