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

pub mod canfd;
pub mod cascade;
pub mod compensator;
pub mod drive;
pub mod faults;
pub mod foc;
pub mod message;
pub mod predictors;
pub mod profile;
pub mod startup;

pub use cascade::{CascadeConfig, JointReference, Pid, PositionVelocityCascade};
pub use compensator::{
    BusClock, Compensator, CompensatorConfig, CompensatorOutput, ConfigError, FeedforwardSource,
    NoPredictor, PredictorInput, TorquePredictor,
};
pub use drive::{DriveConfig, DriveOutput, JointDrive, SensorSample};
pub use faults::FaultFlags;
pub use foc::{CurrentLoop, CurrentLoopConfig, MotorParameters};
pub use message::{FrameReceiver, JointState, JointStateMessage, SEQUENCE_WINDOW, StateLimits};
pub use predictors::{DecoupledJointModel, LstmPredictor, SubsetModel, TorqueNetwork};
pub use profile::JointProfile;
pub use startup::{
    JointConfigBlock, JointConfigFault, JointSlot, StartupPlan, plan_startup, select_joint,
};

/// `x` limited to [-limit, limit] without a panic path (`f32::clamp` asserts its
/// bounds): a negative or NaN limit counts as 0, a NaN `x` gives 0.
#[inline]
pub fn clamp_abs(x: f32, limit: f32) -> f32 {
    let l = if limit >= 0.0 { limit } else { 0.0 };
    if x > l {
        l
    } else if x < -l {
        -l
    } else if !x.is_nan() {
        x
    } else {
        0.0
    }
}

/// True when |x| <= limit; false for a NaN `x` or limit.
#[inline]
pub fn within(x: f32, limit: f32) -> bool {
    x.abs() <= limit
}
