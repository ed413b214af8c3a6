from google.protobuf.internal import containers as _containers
from google.protobuf.internal import enum_type_wrapper as _enum_type_wrapper
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class ErrorCode(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
    __slots__ = ()
    ERROR_CODE_UNSPECIFIED: _ClassVar[ErrorCode]
    ERROR_CODE_MALFORMED: _ClassVar[ErrorCode]
    ERROR_CODE_WRONG_TYPE: _ClassVar[ErrorCode]
    ERROR_CODE_UNKNOWN_SESSION: _ClassVar[ErrorCode]
    ERROR_CODE_NO_SUCH_FRAME: _ClassVar[ErrorCode]
    ERROR_CODE_NO_SUCH_HYPOTHESIS: _ClassVar[ErrorCode]
    ERROR_CODE_TOO_LARGE: _ClassVar[ErrorCode]
    ERROR_CODE_BAD_IMAGE: _ClassVar[ErrorCode]
    ERROR_CODE_BAD_CAMERA: _ClassVar[ErrorCode]
    ERROR_CODE_DEGENERATE: _ClassVar[ErrorCode]
    ERROR_CODE_OVERLOADED: _ClassVar[ErrorCode]
    ERROR_CODE_FORBIDDEN: _ClassVar[ErrorCode]
    ERROR_CODE_INTERNAL: _ClassVar[ErrorCode]
ERROR_CODE_UNSPECIFIED: ErrorCode
ERROR_CODE_MALFORMED: ErrorCode
ERROR_CODE_WRONG_TYPE: ErrorCode
ERROR_CODE_UNKNOWN_SESSION: ErrorCode
ERROR_CODE_NO_SUCH_FRAME: ErrorCode
ERROR_CODE_NO_SUCH_HYPOTHESIS: ErrorCode
ERROR_CODE_TOO_LARGE: ErrorCode
ERROR_CODE_BAD_IMAGE: ErrorCode
ERROR_CODE_BAD_CAMERA: ErrorCode
ERROR_CODE_DEGENERATE: ErrorCode
ERROR_CODE_OVERLOADED: ErrorCode
ERROR_CODE_FORBIDDEN: ErrorCode
ERROR_CODE_INTERNAL: ErrorCode

class Error(_message.Message):
    __slots__ = ("schema", "session", "key", "code", "message", "time_ns", "service")
    SCHEMA_FIELD_NUMBER: _ClassVar[int]
    SESSION_FIELD_NUMBER: _ClassVar[int]
    KEY_FIELD_NUMBER: _ClassVar[int]
    CODE_FIELD_NUMBER: _ClassVar[int]
    MESSAGE_FIELD_NUMBER: _ClassVar[int]
    TIME_NS_FIELD_NUMBER: _ClassVar[int]
    SERVICE_FIELD_NUMBER: _ClassVar[int]
    schema: str
    session: str
    key: str
    code: ErrorCode
    message: str
    time_ns: int
    service: str
    def __init__(self, schema: _Optional[str] = ..., session: _Optional[str] = ..., key: _Optional[str] = ..., code: _Optional[_Union[ErrorCode, str]] = ..., message: _Optional[str] = ..., time_ns: _Optional[int] = ..., service: _Optional[str] = ...) -> None: ...

class ServiceStatus(_message.Message):
    __slots__ = ("schema", "service", "instance", "started_ns", "time_ns", "frames_in", "results_out", "errors", "dropped", "queue_depth", "version", "counters")
    class CountersEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: _Optional[str] = ..., value: _Optional[int] = ...) -> None: ...
    SCHEMA_FIELD_NUMBER: _ClassVar[int]
    SERVICE_FIELD_NUMBER: _ClassVar[int]
    INSTANCE_FIELD_NUMBER: _ClassVar[int]
    STARTED_NS_FIELD_NUMBER: _ClassVar[int]
    TIME_NS_FIELD_NUMBER: _ClassVar[int]
    FRAMES_IN_FIELD_NUMBER: _ClassVar[int]
    RESULTS_OUT_FIELD_NUMBER: _ClassVar[int]
    ERRORS_FIELD_NUMBER: _ClassVar[int]
    DROPPED_FIELD_NUMBER: _ClassVar[int]
    QUEUE_DEPTH_FIELD_NUMBER: _ClassVar[int]
    VERSION_FIELD_NUMBER: _ClassVar[int]
    COUNTERS_FIELD_NUMBER: _ClassVar[int]
    schema: str
    service: str
    instance: str
    started_ns: int
    time_ns: int
    frames_in: int
    results_out: int
    errors: int
    dropped: int
    queue_depth: int
    version: str
    counters: _containers.ScalarMap[str, int]
    def __init__(self, schema: _Optional[str] = ..., service: _Optional[str] = ..., instance: _Optional[str] = ..., started_ns: _Optional[int] = ..., time_ns: _Optional[int] = ..., frames_in: _Optional[int] = ..., results_out: _Optional[int] = ..., errors: _Optional[int] = ..., dropped: _Optional[int] = ..., queue_depth: _Optional[int] = ..., version: _Optional[str] = ..., counters: _Optional[_Mapping[str, int]] = ...) -> None: ...
