//! What several firmware test files share.
use firmware::control::{CascadeConfig, CurrentLoopConfig, DriveConfig, MotorParameters};

/// The drive the control tests run: the board's motor at 20 kHz PWM, gear 100, outer loops
/// at 5 kHz, an encoder offset of 0.1 rad, a 18-60 V bus window.
pub fn drive_config() -> DriveConfig {
    DriveConfig {
        current: CurrentLoopConfig::tuned(MotorParameters::BOARD, 20_000.0),
        cascade: CascadeConfig {
            rate_hz: 5000.0,
            position_kp: 50.0,
            position_ki: 1.0,
            position_kd: 0.01,
            max_velocity_rad_s: 3.0,
            velocity_kp: 5.0,
            velocity_ki: 50.0,
            velocity_kd: 0.001,
            max_current_a: 10.0,
            velocity_filter_alpha: 0.2,
        },
        gear_ratio: 100.0,
        encoder_offset_rad: 0.1,
        max_current_a: 12.0,
        overcurrent_trip_a: 20.0,
        bus_min_v: 18.0,
        bus_max_v: 60.0,
        max_abs_q_ref_rad: 7.0,
    }
}
