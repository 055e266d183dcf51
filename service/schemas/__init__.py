"""Wire models shared by the REST API and the SDK (pydantic + stdlib only)."""

from service.schemas.analysis import (
    Alarm,
    Classification,
    Flag,
    Fundamental,
    Measurement,
    Mode,
    PaperRule,
    Prediction,
    RecordDetection,
    SweepResult,
    Truth,
)
from service.schemas.common import (
    PROBLEM_MEDIA_TYPE,
    PROBLEM_TYPE_PREFIX,
    Control,
    FieldError,
    Health,
    Problem,
)
from service.schemas.detections import Detection, DetectionFlag, DetectionRequest
from service.schemas.jobs import TERMINAL_STATUSES, Job, JobError, JobPage, JobStatus, Progress
from service.schemas.signals import SignalData, SignalIn, SignalMeta, SignalPage
from service.schemas.simulations import SimulationRequest, SimulationResult
from service.schemas.sweeps import (
    SimulatedSweep,
    Sweep,
    SweepMeasurement,
    SweepPage,
    SweepRequest,
)

__all__ = [
    "Alarm",
    "Classification",
    "Flag",
    "Fundamental",
    "Measurement",
    "Mode",
    "PaperRule",
    "Prediction",
    "RecordDetection",
    "SweepResult",
    "Truth",
    "PROBLEM_MEDIA_TYPE",
    "PROBLEM_TYPE_PREFIX",
    "TERMINAL_STATUSES",
    "Control",
    "Detection",
    "DetectionFlag",
    "DetectionRequest",
    "FieldError",
    "Health",
    "Job",
    "JobError",
    "JobPage",
    "JobStatus",
    "Problem",
    "Progress",
    "SignalData",
    "SignalIn",
    "SignalMeta",
    "SignalPage",
    "SimulatedSweep",
    "SimulationRequest",
    "SimulationResult",
    "Sweep",
    "SweepMeasurement",
    "SweepPage",
    "SweepRequest",
]
