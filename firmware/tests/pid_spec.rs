//! The cascade's PID against values worked out by hand from its specification:
//! `feedforward + kp e + ki int(e) - kd d(measurement)/dt`, the derivative on the
//! measurement through `d += alpha (raw - d)`, none on the first step after a reset,
//! the integral bounded by the limit.

use firmware::control::Pid;

const DT: f32 = 0.01;

fn close(a: f32, b: f32) -> bool {
    (a - b).abs() <= 1e-5 * b.abs().max(1.0)
}

#[test]
fn proportional_and_feedforward() {
    let mut pid = Pid::new(2.0, 0.0, 0.0, 1.0, 10.0);
    // 0.5 + 2 * (1.0 - 0.25)
    assert!(close(pid.update(1.0, 0.25, 0.5, DT), 2.0));
    assert!(close(pid.update(-1.0, 0.5, 0.0, DT), -3.0));
    assert_eq!(pid.integral(), 0.0);
}

#[test]
fn the_integral_grows_by_ki_e_dt_and_is_its_output_share() {
    let mut pid = Pid::new(0.0, 10.0, 0.0, 1.0, 10.0);
    for n in 1..=5 {
        let out = pid.update(1.0, 0.0, 0.0, DT);
        // ki * e * dt = 0.1 per step.
        assert!(close(pid.integral(), 0.1 * n as f32), "{}", pid.integral());
        assert!(close(out, 0.1 * n as f32), "{out}");
    }
    // A negative error integrates down.
    let out = pid.update(0.0, 2.0, 0.0, DT);
    assert!(close(pid.integral(), 0.3) && close(out, 0.3), "{out}");
}

#[test]
fn the_derivative_acts_on_the_measurement_through_the_filter() {
    // Unfiltered: the measurement rises 0.1 in one step of 10 ms: 10 per second.
    let mut pid = Pid::new(0.0, 0.0, 0.5, 1.0, 100.0);
    assert_eq!(pid.update(0.0, 0.0, 0.0, DT), 0.0);
    assert!(close(pid.update(0.1, 0.1, 0.0, DT), -5.0));
    // Falling: +5.
    assert!(close(pid.update(0.0, 0.0, 0.0, DT), 5.0));
    // Filtered with alpha 0.25: d = 2.5, then 2.5 + 0.25 (0 - 2.5) = 1.875.
    let mut pid = Pid::new(0.0, 0.0, 0.5, 0.25, 100.0);
    pid.update(0.0, 0.0, 0.0, DT);
    assert!(close(pid.update(0.1, 0.1, 0.0, DT), -1.25));
    assert!(close(pid.update(0.1, 0.1, 0.0, DT), -0.9375));
    // Another step length: 0.1 in 20 ms is 5 per second.
    let mut pid = Pid::new(0.0, 0.0, 1.0, 1.0, 100.0);
    pid.update(0.3, 0.3, 0.0, 0.02);
    assert!(close(pid.update(0.4, 0.4, 0.0, 0.02), -5.0));
}

#[test]
fn reset_empties_the_integrator_and_the_derivative_history() {
    let mut pid = Pid::new(0.0, 10.0, 0.5, 0.5, 10.0);
    for _ in 0..3 {
        pid.update(1.0, 0.0, 0.0, DT);
    }
    pid.update(1.0, 0.2, 0.0, DT);
    assert!(pid.integral() > 0.3);
    pid.reset();
    assert_eq!(pid.integral(), 0.0);
    // First step after the reset: no derivative kick from the old measurement, no
    // old filter state, no old integral (error 0).
    assert_eq!(pid.update(5.0, 5.0, 0.0, DT), 0.0);
    // The next step's derivative starts from zero: 0.5 * (0.5 * 10) = 2.5.
    assert!(close(pid.update(5.1, 5.1, 0.0, DT), -2.5));
}

#[test]
fn the_integrator_holds_while_the_error_pushes_further_into_the_limit() {
    // kp e alone (10) is beyond the limit (1): with e > 0 at the upper limit and e < 0
    // at the lower one the integral holds.
    let mut pid = Pid::new(10.0, 10.0, 0.0, 1.0, 1.0);
    for _ in 0..5 {
        assert_eq!(pid.update(1.0, 0.0, 0.0, DT), 1.0);
        assert_eq!(pid.integral(), 0.0);
        assert_eq!(pid.update(-1.0, 0.0, 0.0, DT), -1.0);
        assert_eq!(pid.integral(), 0.0);
    }
    // Saturated by the feedforward but with an error that pulls back: it integrates
    // (ki e dt = 10 * -0.1 * 0.01 = -0.01 per step), and likewise at the lower limit.
    let mut pid = Pid::new(1.0, 10.0, 0.0, 1.0, 1.0);
    pid.update(0.0, 0.1, 5.0, DT);
    assert!(close(pid.integral(), -0.01), "{}", pid.integral());
    pid.update(0.1, 0.0, -5.0, DT);
    assert!(close(pid.integral(), 0.0), "{}", pid.integral());
    pid.update(0.1, 0.0, -5.0, DT);
    assert!(close(pid.integral(), 0.01), "{}", pid.integral());
    // Within the limit it integrates whatever the sign.
    let mut pid = Pid::new(0.1, 10.0, 0.0, 1.0, 1.0);
    pid.update(1.0, 0.0, 0.0, DT);
    pid.update(-1.0, 0.0, 0.0, DT);
    pid.update(-1.0, 0.0, 0.0, DT);
    assert!(close(pid.integral(), -0.1), "{}", pid.integral());
}

#[test]
fn an_output_exactly_at_the_limit_still_integrates() {
    // ff 0.25 + kp e 0.5 + ki e dt 0.25 = 1.0, the limit, exactly (all binary
    // fractions): not beyond it, so the integral takes the step.
    let mut pid = Pid::new(1.0, 1.0, 0.0, 1.0, 1.0);
    assert_eq!(pid.update(0.5, 0.0, 0.25, 0.5), 1.0);
    assert_eq!(pid.integral(), 0.25);
    let mut pid = Pid::new(1.0, 1.0, 0.0, 1.0, 1.0);
    assert_eq!(pid.update(-0.5, 0.0, -0.25, 0.5), -1.0);
    assert_eq!(pid.integral(), -0.25);
}

#[test]
fn a_lowered_limit_bounds_the_integral_even_with_zero_error() {
    for sign in [1.0f32, -1.0] {
        let mut pid = Pid::new(0.0, 10.0, 0.0, 1.0, 1.0);
        for _ in 0..5 {
            pid.update(sign, 0.0, 0.0, DT);
        }
        assert!(close(pid.integral(), 0.5 * sign));
        // The limit drops to 0.2 while the feedforward saturates the output and the
        // error is zero: the integral is bounded by the new limit.
        pid.output_limit = 0.2;
        assert_eq!(pid.update(0.0, 0.0, 5.0 * sign, DT), 0.2 * sign);
        assert_eq!(pid.integral(), 0.2 * sign);
    }
}

#[test]
fn a_step_of_zero_length_does_not_poison_the_derivative() {
    // dt = 0 with a moving measurement gives an infinite derivative: the controller
    // starts afresh, and the next ordinary steps are those of a fresh controller.
    let mut pid = Pid::new(1.0, 0.0, 0.5, 0.5, 100.0);
    pid.update(0.0, 0.0, 0.0, DT);
    let out = pid.update(0.0, 0.1, 0.0, 0.0);
    assert!(out.is_finite());
    let mut fresh = Pid::new(1.0, 0.0, 0.5, 0.5, 100.0);
    for m in [0.2, 0.3, 0.3] {
        assert_eq!(pid.update(0.0, m, 0.0, DT), fresh.update(0.0, m, 0.0, DT));
    }
    // Fresh: first step -0.2 (no derivative), then -0.3 - 0.5 * 0.5 * 10 = -2.8.
    let mut again = Pid::new(1.0, 0.0, 0.5, 0.5, 100.0);
    assert!(close(again.update(0.0, 0.2, 0.0, DT), -0.2));
    assert!(close(again.update(0.0, 0.3, 0.0, DT), -2.8));
}

#[test]
fn the_cascade_reset_empties_both_integrators() {
    use firmware::control::{CascadeConfig, JointReference, PositionVelocityCascade};
    let mut c = PositionVelocityCascade::new(CascadeConfig {
        rate_hz: 1000.0,
        position_kp: 1.0,
        position_ki: 5.0,
        position_kd: 0.0,
        max_velocity_rad_s: 3.0,
        velocity_kp: 0.1,
        velocity_ki: 5.0,
        velocity_kd: 0.0,
        max_current_a: 10.0,
        velocity_filter_alpha: 1.0,
    });
    let r = JointReference {
        q_rad: 0.5,
        ..Default::default()
    };
    for _ in 0..20 {
        c.step(&r, 0.0, 0.0);
    }
    assert!(c.position.integral() > 0.0 && c.velocity.integral() > 0.0);
    c.reset();
    assert_eq!((c.position.integral(), c.velocity.integral()), (0.0, 0.0));
}
