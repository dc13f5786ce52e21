//! The per-joint control loop: FOC current loop at the PWM rate, position and
//! velocity loops at a decimation of it, and the torque feedforward compensator
//! (identified model + LSTM behind [`TorquePredictor`]) with its safety chain.
//!
//! Data flow on one joint MCU:
//!
//! ```text
//! bus: JointStateMessage (other joints) --> Compensator::receive
//! compensator tick (100 Hz .. kHz):  Compensator::tick(own state) --> current_a
//!                                    --> JointDrive::set_feedforward_current (held)
//! PWM tick (20 kHz): SensorSample --> JointDrive::pwm_tick --> three duties
//!                    (outer loops every n-th tick: position -> velocity -> iq)
//! ```
//!
//! No heap, no panics, no unbounded loops: every call does a fixed amount of work
//! (loops run over the const-generic number of joints or over fixed arrays).

pub mod cascade;
pub mod compensator;
pub mod drive;
pub mod faults;
pub mod foc;
pub mod message;
pub mod predictors;

pub use cascade::{CascadeConfig, JointReference, Pid, PositionVelocityCascade};
pub use compensator::{
    Compensator, CompensatorConfig, CompensatorOutput, ConfigError, FeedforwardSource, NoPredictor,
    PredictorInput, TorquePredictor,
};
pub use drive::{DriveConfig, DriveOutput, JointDrive, SensorSample};
pub use faults::FaultFlags;
pub use foc::{CurrentLoop, CurrentLoopConfig, MotorParameters};
pub use message::{FrameReceiver, JointState, JointStateMessage, StateLimits};
pub use predictors::DecoupledJointModel;
