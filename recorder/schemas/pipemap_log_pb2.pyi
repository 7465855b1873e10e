from google.protobuf.internal import containers as _containers
from google.protobuf.internal import enum_type_wrapper as _enum_type_wrapper
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from typing import ClassVar as _ClassVar, Iterable as _Iterable, Mapping as _Mapping, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class Ranges(_message.Message):
    __slots__ = ("time_ns", "front_m", "front_left_m", "front_right_m", "max_range_m")
    TIME_NS_FIELD_NUMBER: _ClassVar[int]
    FRONT_M_FIELD_NUMBER: _ClassVar[int]
    FRONT_LEFT_M_FIELD_NUMBER: _ClassVar[int]
    FRONT_RIGHT_M_FIELD_NUMBER: _ClassVar[int]
    MAX_RANGE_M_FIELD_NUMBER: _ClassVar[int]
    time_ns: int
    front_m: float
    front_left_m: float
    front_right_m: float
    max_range_m: float
    def __init__(self, time_ns: _Optional[int] = ..., front_m: _Optional[float] = ..., front_left_m: _Optional[float] = ..., front_right_m: _Optional[float] = ..., max_range_m: _Optional[float] = ...) -> None: ...

class Imu(_message.Message):
    __slots__ = ("time_ns", "yaw_rate_rps", "accel_forward_mps2", "accel_left_mps2")
    TIME_NS_FIELD_NUMBER: _ClassVar[int]
    YAW_RATE_RPS_FIELD_NUMBER: _ClassVar[int]
    ACCEL_FORWARD_MPS2_FIELD_NUMBER: _ClassVar[int]
    ACCEL_LEFT_MPS2_FIELD_NUMBER: _ClassVar[int]
    time_ns: int
    yaw_rate_rps: float
    accel_forward_mps2: float
    accel_left_mps2: float
    def __init__(self, time_ns: _Optional[int] = ..., yaw_rate_rps: _Optional[float] = ..., accel_forward_mps2: _Optional[float] = ..., accel_left_mps2: _Optional[float] = ...) -> None: ...

class WheelEncoders(_message.Message):
    __slots__ = ("time_ns", "left_ticks", "right_ticks", "ticks_per_rev", "wheel_diameter_m")
    TIME_NS_FIELD_NUMBER: _ClassVar[int]
    LEFT_TICKS_FIELD_NUMBER: _ClassVar[int]
    RIGHT_TICKS_FIELD_NUMBER: _ClassVar[int]
    TICKS_PER_REV_FIELD_NUMBER: _ClassVar[int]
    WHEEL_DIAMETER_M_FIELD_NUMBER: _ClassVar[int]
    time_ns: int
    left_ticks: int
    right_ticks: int
    ticks_per_rev: int
    wheel_diameter_m: float
    def __init__(self, time_ns: _Optional[int] = ..., left_ticks: _Optional[int] = ..., right_ticks: _Optional[int] = ..., ticks_per_rev: _Optional[int] = ..., wheel_diameter_m: _Optional[float] = ...) -> None: ...

class ControllerState(_message.Message):
    __slots__ = ("time_ns", "state", "linear_mps", "angular_rps", "heading_estimate_rad", "x_estimate_m", "y_estimate_m")
    TIME_NS_FIELD_NUMBER: _ClassVar[int]
    STATE_FIELD_NUMBER: _ClassVar[int]
    LINEAR_MPS_FIELD_NUMBER: _ClassVar[int]
    ANGULAR_RPS_FIELD_NUMBER: _ClassVar[int]
    HEADING_ESTIMATE_RAD_FIELD_NUMBER: _ClassVar[int]
    X_ESTIMATE_M_FIELD_NUMBER: _ClassVar[int]
    Y_ESTIMATE_M_FIELD_NUMBER: _ClassVar[int]
    time_ns: int
    state: str
    linear_mps: float
    angular_rps: float
    heading_estimate_rad: float
    x_estimate_m: float
    y_estimate_m: float
    def __init__(self, time_ns: _Optional[int] = ..., state: _Optional[str] = ..., linear_mps: _Optional[float] = ..., angular_rps: _Optional[float] = ..., heading_estimate_rad: _Optional[float] = ..., x_estimate_m: _Optional[float] = ..., y_estimate_m: _Optional[float] = ...) -> None: ...

class SweepCommand(_message.Message):
    __slots__ = ("time_ns", "phase", "sweep_id", "visit_id", "image_index", "image_count", "camera_angle_rad", "fov_rad", "probe", "probe_kind", "probe_yaw_rad", "probe_forward_m", "probe_left_m", "imu_roll_rad", "imu_pitch_rad")
    class Phase(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
        __slots__ = ()
        PHASE_UNSPECIFIED: _ClassVar[SweepCommand.Phase]
        START: _ClassVar[SweepCommand.Phase]
        IMAGE: _ClassVar[SweepCommand.Phase]
        END: _ClassVar[SweepCommand.Phase]
    PHASE_UNSPECIFIED: SweepCommand.Phase
    START: SweepCommand.Phase
    IMAGE: SweepCommand.Phase
    END: SweepCommand.Phase
    TIME_NS_FIELD_NUMBER: _ClassVar[int]
    PHASE_FIELD_NUMBER: _ClassVar[int]
    SWEEP_ID_FIELD_NUMBER: _ClassVar[int]
    VISIT_ID_FIELD_NUMBER: _ClassVar[int]
    IMAGE_INDEX_FIELD_NUMBER: _ClassVar[int]
    IMAGE_COUNT_FIELD_NUMBER: _ClassVar[int]
    CAMERA_ANGLE_RAD_FIELD_NUMBER: _ClassVar[int]
    FOV_RAD_FIELD_NUMBER: _ClassVar[int]
    PROBE_FIELD_NUMBER: _ClassVar[int]
    PROBE_KIND_FIELD_NUMBER: _ClassVar[int]
    PROBE_YAW_RAD_FIELD_NUMBER: _ClassVar[int]
    PROBE_FORWARD_M_FIELD_NUMBER: _ClassVar[int]
    PROBE_LEFT_M_FIELD_NUMBER: _ClassVar[int]
    IMU_ROLL_RAD_FIELD_NUMBER: _ClassVar[int]
    IMU_PITCH_RAD_FIELD_NUMBER: _ClassVar[int]
    time_ns: int
    phase: SweepCommand.Phase
    sweep_id: int
    visit_id: int
    image_index: int
    image_count: int
    camera_angle_rad: float
    fov_rad: float
    probe: bool
    probe_kind: str
    probe_yaw_rad: float
    probe_forward_m: float
    probe_left_m: float
    imu_roll_rad: float
    imu_pitch_rad: float
    def __init__(self, time_ns: _Optional[int] = ..., phase: _Optional[_Union[SweepCommand.Phase, str]] = ..., sweep_id: _Optional[int] = ..., visit_id: _Optional[int] = ..., image_index: _Optional[int] = ..., image_count: _Optional[int] = ..., camera_angle_rad: _Optional[float] = ..., fov_rad: _Optional[float] = ..., probe: bool = ..., probe_kind: _Optional[str] = ..., probe_yaw_rad: _Optional[float] = ..., probe_forward_m: _Optional[float] = ..., probe_left_m: _Optional[float] = ..., imu_roll_rad: _Optional[float] = ..., imu_pitch_rad: _Optional[float] = ...) -> None: ...

class NodeEvent(_message.Message):
    __slots__ = ("time_ns", "kind", "visit_id", "exits", "exit_rad", "exits_rad", "x_estimate_m", "y_estimate_m", "odometer_m")
    class Kind(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
        __slots__ = ()
        KIND_UNSPECIFIED: _ClassVar[NodeEvent.Kind]
        ARRIVAL: _ClassVar[NodeEvent.Kind]
        DEPARTURE: _ClassVar[NodeEvent.Kind]
        EXITS: _ClassVar[NodeEvent.Kind]
    KIND_UNSPECIFIED: NodeEvent.Kind
    ARRIVAL: NodeEvent.Kind
    DEPARTURE: NodeEvent.Kind
    EXITS: NodeEvent.Kind
    TIME_NS_FIELD_NUMBER: _ClassVar[int]
    KIND_FIELD_NUMBER: _ClassVar[int]
    VISIT_ID_FIELD_NUMBER: _ClassVar[int]
    EXITS_FIELD_NUMBER: _ClassVar[int]
    EXIT_RAD_FIELD_NUMBER: _ClassVar[int]
    EXITS_RAD_FIELD_NUMBER: _ClassVar[int]
    X_ESTIMATE_M_FIELD_NUMBER: _ClassVar[int]
    Y_ESTIMATE_M_FIELD_NUMBER: _ClassVar[int]
    ODOMETER_M_FIELD_NUMBER: _ClassVar[int]
    time_ns: int
    kind: NodeEvent.Kind
    visit_id: int
    exits: int
    exit_rad: float
    exits_rad: _containers.RepeatedScalarFieldContainer[float]
    x_estimate_m: float
    y_estimate_m: float
    odometer_m: float
    def __init__(self, time_ns: _Optional[int] = ..., kind: _Optional[_Union[NodeEvent.Kind, str]] = ..., visit_id: _Optional[int] = ..., exits: _Optional[int] = ..., exit_rad: _Optional[float] = ..., exits_rad: _Optional[_Iterable[float]] = ..., x_estimate_m: _Optional[float] = ..., y_estimate_m: _Optional[float] = ..., odometer_m: _Optional[float] = ...) -> None: ...

class ProbeResult(_message.Message):
    __slots__ = ("kind", "similarity", "improved")
    KIND_FIELD_NUMBER: _ClassVar[int]
    SIMILARITY_FIELD_NUMBER: _ClassVar[int]
    IMPROVED_FIELD_NUMBER: _ClassVar[int]
    kind: str
    similarity: float
    improved: bool
    def __init__(self, kind: _Optional[str] = ..., similarity: _Optional[float] = ..., improved: bool = ...) -> None: ...

class Decision(_message.Message):
    __slots__ = ("time_ns", "visit_id", "node", "known", "candidate", "similarity", "margin", "image_shift", "pixel_shift", "rotation_rad", "rotation_pinhole_rad", "probes", "threshold", "exit_ports", "arrival_port", "rejected", "hypotheses", "deferred", "settled")
    TIME_NS_FIELD_NUMBER: _ClassVar[int]
    VISIT_ID_FIELD_NUMBER: _ClassVar[int]
    NODE_FIELD_NUMBER: _ClassVar[int]
    KNOWN_FIELD_NUMBER: _ClassVar[int]
    CANDIDATE_FIELD_NUMBER: _ClassVar[int]
    SIMILARITY_FIELD_NUMBER: _ClassVar[int]
    MARGIN_FIELD_NUMBER: _ClassVar[int]
    IMAGE_SHIFT_FIELD_NUMBER: _ClassVar[int]
    PIXEL_SHIFT_FIELD_NUMBER: _ClassVar[int]
    ROTATION_RAD_FIELD_NUMBER: _ClassVar[int]
    ROTATION_PINHOLE_RAD_FIELD_NUMBER: _ClassVar[int]
    PROBES_FIELD_NUMBER: _ClassVar[int]
    THRESHOLD_FIELD_NUMBER: _ClassVar[int]
    EXIT_PORTS_FIELD_NUMBER: _ClassVar[int]
    ARRIVAL_PORT_FIELD_NUMBER: _ClassVar[int]
    REJECTED_FIELD_NUMBER: _ClassVar[int]
    HYPOTHESES_FIELD_NUMBER: _ClassVar[int]
    DEFERRED_FIELD_NUMBER: _ClassVar[int]
    SETTLED_FIELD_NUMBER: _ClassVar[int]
    time_ns: int
    visit_id: int
    node: int
    known: bool
    candidate: int
    similarity: float
    margin: float
    image_shift: int
    pixel_shift: float
    rotation_rad: float
    rotation_pinhole_rad: float
    probes: _containers.RepeatedCompositeFieldContainer[ProbeResult]
    threshold: float
    exit_ports: _containers.RepeatedScalarFieldContainer[int]
    arrival_port: int
    rejected: _containers.RepeatedScalarFieldContainer[int]
    hypotheses: int
    deferred: _containers.RepeatedScalarFieldContainer[int]
    settled: _containers.RepeatedCompositeFieldContainer[SettledVisit]
    def __init__(self, time_ns: _Optional[int] = ..., visit_id: _Optional[int] = ..., node: _Optional[int] = ..., known: bool = ..., candidate: _Optional[int] = ..., similarity: _Optional[float] = ..., margin: _Optional[float] = ..., image_shift: _Optional[int] = ..., pixel_shift: _Optional[float] = ..., rotation_rad: _Optional[float] = ..., rotation_pinhole_rad: _Optional[float] = ..., probes: _Optional[_Iterable[_Union[ProbeResult, _Mapping]]] = ..., threshold: _Optional[float] = ..., exit_ports: _Optional[_Iterable[int]] = ..., arrival_port: _Optional[int] = ..., rejected: _Optional[_Iterable[int]] = ..., hypotheses: _Optional[int] = ..., deferred: _Optional[_Iterable[int]] = ..., settled: _Optional[_Iterable[_Union[SettledVisit, _Mapping]]] = ...) -> None: ...

class SettledVisit(_message.Message):
    __slots__ = ("visit", "node")
    VISIT_FIELD_NUMBER: _ClassVar[int]
    NODE_FIELD_NUMBER: _ClassVar[int]
    visit: int
    node: int
    def __init__(self, visit: _Optional[int] = ..., node: _Optional[int] = ...) -> None: ...

class TrueSweep(_message.Message):
    __slots__ = ("time_ns", "sweep_id", "visit_id", "node", "x_m", "y_m", "z_m", "yaw_rad", "roll_rad", "pitch_rad")
    TIME_NS_FIELD_NUMBER: _ClassVar[int]
    SWEEP_ID_FIELD_NUMBER: _ClassVar[int]
    VISIT_ID_FIELD_NUMBER: _ClassVar[int]
    NODE_FIELD_NUMBER: _ClassVar[int]
    X_M_FIELD_NUMBER: _ClassVar[int]
    Y_M_FIELD_NUMBER: _ClassVar[int]
    Z_M_FIELD_NUMBER: _ClassVar[int]
    YAW_RAD_FIELD_NUMBER: _ClassVar[int]
    ROLL_RAD_FIELD_NUMBER: _ClassVar[int]
    PITCH_RAD_FIELD_NUMBER: _ClassVar[int]
    time_ns: int
    sweep_id: int
    visit_id: int
    node: str
    x_m: float
    y_m: float
    z_m: float
    yaw_rad: float
    roll_rad: float
    pitch_rad: float
    def __init__(self, time_ns: _Optional[int] = ..., sweep_id: _Optional[int] = ..., visit_id: _Optional[int] = ..., node: _Optional[str] = ..., x_m: _Optional[float] = ..., y_m: _Optional[float] = ..., z_m: _Optional[float] = ..., yaw_rad: _Optional[float] = ..., roll_rad: _Optional[float] = ..., pitch_rad: _Optional[float] = ...) -> None: ...
