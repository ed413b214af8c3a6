from google.protobuf.internal import enum_type_wrapper as _enum_type_wrapper
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class SelectedBy(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    SELECTED_BY_UNSPECIFIED: _ClassVar[SelectedBy]
    SELECTED_BY_USER: _ClassVar[SelectedBy]
    SELECTED_BY_AUTO: _ClassVar[SelectedBy]
SELECTED_BY_UNSPECIFIED: SelectedBy
SELECTED_BY_USER: SelectedBy
SELECTED_BY_AUTO: SelectedBy

class Selection(_message.Message):
    __slots__ = ("schema", "session", "index", "rank", "by", "time_ns", "camera_height_m", "camera_height_sigma_m")
    SCHEMA_FIELD_NUMBER: _ClassVar[int]
    SESSION_FIELD_NUMBER: _ClassVar[int]
    INDEX_FIELD_NUMBER: _ClassVar[int]
    RANK_FIELD_NUMBER: _ClassVar[int]
    BY_FIELD_NUMBER: _ClassVar[int]
    TIME_NS_FIELD_NUMBER: _ClassVar[int]
    CAMERA_HEIGHT_M_FIELD_NUMBER: _ClassVar[int]
    CAMERA_HEIGHT_SIGMA_M_FIELD_NUMBER: _ClassVar[int]
    schema: str
    session: str
    index: int
    rank: int
    by: SelectedBy
    time_ns: int
    camera_height_m: float
    camera_height_sigma_m: float
    def __init__(self, schema: _Optional[str] = ..., session: _Optional[str] = ..., index: _Optional[int] = ..., rank: _Optional[int] = ..., by: _Optional[_Union[SelectedBy, str]] = ..., time_ns: _Optional[int] = ..., camera_height_m: _Optional[float] = ..., camera_height_sigma_m: _Optional[float] = ...) -> None: ...
