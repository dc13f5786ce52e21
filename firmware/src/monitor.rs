//! The drive's online do-no-harm monitor: is the compensation helping this joint now?
//!
//! Every tick the compensator has two candidates for the torque it feeds forward: the
//! identified model alone (`base`) and the model plus everything learned or adapted
//! beyond it (`full`: the linear stage, the LSTM's correction, the online friction
//! adaptation, after the envelope's fade). The drive measures, a tick later, the torque
//! the joint actually needed. The monitor scores both candidates **in shadow**, on what
//! each predicted for that tick, whatever gain was applied: a compensation that has been
//! faded keeps being scored and can prove itself again.
//!
//! **The score.** With `e = measured - base` (the model's error) and
//! `c = full - base` (the compensation), the error of the blend `base + g c` is `e - g c`,
//! and its mean square over a window is `M - 2 g S_ec + g^2 S_cc`, where `M`, `S_ec`,
//! `S_cc` are exponentially weighted means of `e^2`, `e c` and `c^2` with the time
//! constant `window_s`. The blend that would have done best over the window is
//! `g* = S_ec / S_cc`, clamped to `[0, 1]` (never more than the compensation, never
//! against it). `g = 0` is the model alone, `g = 1` the full compensation; the full
//! compensation is worse than the model alone over the window exactly when
//! `S_cc - 2 S_ec > 0`, that is when `g* < 1/2`.
//!
//! **The gain.** The applied gain follows `g*` at a bounded rate (at most
//! `1 / (fade_s * rate)` per tick, so a full fade takes `fade_s`), with hysteresis: it
//! starts to move once `|g* - g| > hysteresis` and then follows `g*` until it reaches
//! it, and a `g*` within `hysteresis` of 0 or 1 counts as that end, so estimation noise around a good compensation (`g*` near 1) does not make it
//! chatter, and a harmful one is faded all the way. It starts at
//! 1 (the compensation passed the export's gate) and only the measured evidence moves it.
//! The [`crate::control::FaultFlags::COMPENSATION_FADED`] flag is set on every tick
//! whose gain is below 1.
//!
//! **Bounded.** Fixed work per tick (a dozen floating-point operations), no heap, no
//! panic path; a tick whose measured torque or candidates are not finite is not scored;
//! non-finite statistics reset the monitor to a fresh start at its current gain; the
//! gain always stays in `[0, 1]`. Only the torque measured since the previous tick is
//! used (as by the adaptation, [`crate::adaptation`]); after a gap in the inputs the
//! pairing with the previous tick is forgotten ([`DoNoHarmMonitor::restart`]).

/// Settings of the do-no-harm monitor (from the joint profile).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MonitorConfig {
    /// Time constant of the exponentially weighted scores, s: the window over which
    /// compensation and model are compared. Zero (or less than two ticks, or not
    /// finite) turns the monitor off (gain 1).
    pub window_s: f32,
    /// Time the gain takes to move across its whole range `[0, 1]`, s (its rate bound).
    pub fade_s: f32,
    /// Hysteresis of the gain: it starts to follow the window's best blend once that is
    /// farther than this, and follows it until it reaches it; in `[0, 1)`.
    pub hysteresis: f32,
}

impl MonitorConfig {
    /// No monitor: the gain stays 1.
    pub const OFF: MonitorConfig = MonitorConfig {
        window_s: 0.0,
        fade_s: 0.5,
        hysteresis: 0.05,
    };

    /// `(weight of a new sample, largest gain step)` per tick at `tick_hz`, or `None`
    /// when the monitor is off or a setting is unusable.
    pub fn per_tick(&self, tick_hz: f32) -> Option<(f32, f32)> {
        let window_ticks = self.window_s * tick_hz;
        let fade_ticks = self.fade_s * tick_hz;
        let on = window_ticks.is_finite()
            && window_ticks >= 2.0
            && fade_ticks.is_finite()
            && fade_ticks >= 1.0
            && self.hysteresis >= 0.0
            && self.hysteresis < 1.0;
        on.then(|| (1.0 / window_ticks, 1.0 / fade_ticks))
    }
}

/// The monitor's state for one joint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DoNoHarmMonitor {
    alpha: f32,
    max_step: f32,
    hysteresis: f32,
    gain: f32,
    tracking: bool,
    ms_error_nm2: f32,
    mean_error_comp_nm2: f32,
    ms_comp_nm2: f32,
    pending: Option<(f32, f32)>,
}

impl DoNoHarmMonitor {
    /// A monitor ticking at `tick_hz`, gain 1, nothing scored yet (off when `config` is).
    pub fn new(config: MonitorConfig, tick_hz: f32) -> Self {
        let (alpha, max_step) = config.per_tick(tick_hz).unwrap_or((0.0, 0.0));
        Self {
            alpha,
            max_step,
            hysteresis: config.hysteresis,
            gain: 1.0,
            tracking: false,
            ms_error_nm2: 0.0,
            mean_error_comp_nm2: 0.0,
            ms_comp_nm2: 0.0,
            pending: None,
        }
    }

    /// True when the monitor runs.
    pub fn is_on(&self) -> bool {
        self.alpha > 0.0
    }

    /// The gain applied to the compensation, in `[0, 1]`.
    pub fn gain(&self) -> f32 {
        self.gain
    }

    /// The window's best blend `g*` in `[0, 1]` (the gain's target; the current gain
    /// while nothing has been compensated).
    pub fn best_gain(&self) -> f32 {
        if self.ms_comp_nm2 > 0.0 && self.ms_comp_nm2.is_finite() {
            let g = self.mean_error_comp_nm2 / self.ms_comp_nm2;
            if g.is_nan() {
                self.gain
            } else {
                g.clamp(0.0, 1.0)
            }
        } else {
            self.gain
        }
    }

    /// The windowed mean squares of the model alone and of the full compensation,
    /// N*m^2 (`M` and `M - 2 S_ec + S_cc`).
    pub fn scores_nm2(&self) -> (f32, f32) {
        let m = self.ms_error_nm2;
        (m, m - 2.0 * self.mean_error_comp_nm2 + self.ms_comp_nm2)
    }

    /// One tick: score the previous tick's candidates against `measured_nm` (the torque
    /// measured since then), move the gain, remember this tick's candidates `base_nm`
    /// (the model alone) and `full_nm` (with everything beyond it), and return the
    /// torque to feed forward, `base + gain (full - base)`. Off: `full_nm` unchanged.
    pub fn step(&mut self, base_nm: f32, full_nm: f32, measured_nm: f32) -> f32 {
        if !self.is_on() {
            return full_nm;
        }
        if let Some((base_prev, full_prev)) = self.pending.take() {
            self.score(measured_nm - base_prev, full_prev - base_prev);
        }
        if base_nm.is_finite() && full_nm.is_finite() {
            self.pending = Some((base_nm, full_nm));
        }
        let h = self.hysteresis;
        let best = self.best_gain();
        let target = if best >= 1.0 - h {
            1.0
        } else if best <= h {
            0.0
        } else {
            best
        };
        let d = target - self.gain;
        if d.abs() > self.hysteresis {
            self.tracking = true;
        }
        if self.tracking {
            if d.abs() <= self.max_step {
                self.gain += d;
                self.tracking = false;
            } else {
                self.gain += if d > 0.0 {
                    self.max_step
                } else {
                    -self.max_step
                };
            }
        }
        self.gain = if self.gain.is_finite() {
            self.gain.clamp(0.0, 1.0)
        } else {
            0.0
        };
        base_nm + self.gain * (full_nm - base_nm)
    }

    /// Forget the pairing with the previous tick (after a gap in the inputs); the
    /// scores and the gain stay.
    pub fn restart(&mut self) {
        self.pending = None;
    }

    fn score(&mut self, error_nm: f32, comp_nm: f32) {
        if !(error_nm.is_finite() && comp_nm.is_finite()) {
            return;
        }
        let a = self.alpha;
        let m = self.ms_error_nm2 + a * (error_nm * error_nm - self.ms_error_nm2);
        let ec = self.mean_error_comp_nm2 + a * (error_nm * comp_nm - self.mean_error_comp_nm2);
        let cc = self.ms_comp_nm2 + a * (comp_nm * comp_nm - self.ms_comp_nm2);
        if m.is_finite() && ec.is_finite() && cc.is_finite() {
            self.ms_error_nm2 = m;
            self.mean_error_comp_nm2 = ec;
            self.ms_comp_nm2 = cc;
        } else {
            self.ms_error_nm2 = 0.0;
            self.mean_error_comp_nm2 = 0.0;
            self.ms_comp_nm2 = 0.0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ON: MonitorConfig = MonitorConfig {
        window_s: 1.0,
        fade_s: 0.5,
        hysteresis: 0.05,
    };

    /// A deterministic pseudo-random sequence in [-1, 1] (xorshift32).
    fn noise(seed: &mut u32) -> f32 {
        *seed ^= *seed << 13;
        *seed ^= *seed >> 17;
        *seed ^= *seed << 5;
        (*seed as f32 / u32::MAX as f32) * 2.0 - 1.0
    }

    /// Runs `ticks` ticks at 100 Hz where the truth is `truth(k)`, the model predicts
    /// `base(k)` and the compensation `full(k)`; returns the monitor and the RMS errors
    /// of the model, the full compensation and the monitored output.
    fn run(
        m: &mut DoNoHarmMonitor,
        ticks: u32,
        seed: &mut u32,
        base: impl Fn(u32) -> f32,
        full: impl Fn(u32) -> f32,
        truth: impl Fn(u32) -> f32,
    ) -> (f32, f32, f32) {
        let (mut sb, mut sf, mut so) = (0.0f64, 0.0f64, 0.0f64);
        for k in 0..ticks {
            // The torque measured since the previous tick is that tick's truth.
            let measured = if k == 0 { 0.0 } else { truth(k - 1) };
            let out = m.step(base(k), full(k), measured);
            let t = truth(k) + 0.3 * noise(seed);
            sb += ((t - base(k)) as f64).powi(2);
            sf += ((t - full(k)) as f64).powi(2);
            so += ((t - out) as f64).powi(2);
            assert!((0.0..=1.0).contains(&m.gain()));
        }
        let n = ticks as f64;
        (
            (sb / n).sqrt() as f32,
            (sf / n).sqrt() as f32,
            (so / n).sqrt() as f32,
        )
    }

    #[test]
    fn a_harmful_compensation_fades_and_a_good_one_stays() {
        let mut seed = 7;
        let truth = |k: u32| 10.0 * (k as f32 * 0.05).sin() + 2.0;
        let base = |k: u32| 10.0 * (k as f32 * 0.05).sin();
        // Good: the compensation knows the 2 N*m the model misses.
        let mut m = DoNoHarmMonitor::new(ON, 100.0);
        let (rb, rf, ro) = run(&mut m, 2000, &mut seed, base, |k| base(k) + 2.0, truth);
        assert!(rf < 0.5 * rb && ro <= rf * 1.02, "{rb} {rf} {ro}");
        assert!(m.gain() > 0.9, "{}", m.gain());
        // Harmful: it adds 3 N*m the wrong way; the gain fades to 0 within about
        // the window plus the fade, and the output ends near the model's error.
        let mut m = DoNoHarmMonitor::new(ON, 100.0);
        let (rb, rf, ro) = run(&mut m, 2000, &mut seed, base, |k| base(k) - 3.0, truth);
        assert!(rf > 2.0 * rb, "{rb} {rf}");
        assert!(ro < 1.1 * rb, "{rb} {rf} {ro}");
        assert_eq!(m.gain(), 0.0);
    }

    #[test]
    fn a_faded_compensation_proves_itself_again_in_shadow() {
        let mut seed = 11;
        let base = |_k: u32| 0.0;
        // Wrong for the first 10 s, right afterwards.
        let full = |k: u32| if k < 1000 { -2.0 } else { 2.0 };
        let truth = |_k: u32| 2.0;
        let mut m = DoNoHarmMonitor::new(ON, 100.0);
        run(&mut m, 1000, &mut seed, base, full, truth);
        assert_eq!(m.gain(), 0.0);
        let mut gains = [0.0f32; 1000];
        for (k, g) in gains.iter_mut().enumerate() {
            let k = 1000 + k as u32;
            m.step(base(k), full(k), truth(k - 1));
            *g = m.gain();
        }
        // It returns, never faster than the rate bound (0.02 per tick at 0.5 s).
        assert!(gains[999] > 0.95, "{}", gains[999]);
        for w in gains.windows(2) {
            assert!((w[1] - w[0]).abs() <= 0.02 + 1e-6);
        }
    }

    #[test]
    fn the_gain_holds_inside_the_dead_band() {
        // The best blend is 0.97: within 0.05 of 1, the gain stays at 1.
        let mut m = DoNoHarmMonitor::new(ON, 100.0);
        for _ in 0..2000 {
            m.step(0.0, 1.0, 0.97);
        }
        assert!((m.best_gain() - 0.97).abs() < 1e-3, "{}", m.best_gain());
        assert_eq!(m.gain(), 1.0);
        // A best blend of 0.5 pulls it down to within the band of 0.5.
        for _ in 0..2000 {
            m.step(0.0, 1.0, 0.5);
        }
        assert!((m.gain() - 0.5).abs() <= 0.05 + 1e-6, "{}", m.gain());
    }

    #[test]
    fn off_and_bad_input_change_nothing() {
        let mut off = DoNoHarmMonitor::new(MonitorConfig::OFF, 100.0);
        assert!(!off.is_on());
        assert_eq!(off.step(1.0, 5.0, -100.0), 5.0);
        // Settings that cannot run: off.
        for bad in [
            MonitorConfig {
                window_s: f32::NAN,
                ..ON
            },
            MonitorConfig {
                window_s: 0.01,
                ..ON
            },
            MonitorConfig { fade_s: 0.0, ..ON },
            MonitorConfig {
                hysteresis: 1.0,
                ..ON
            },
            MonitorConfig {
                hysteresis: f32::NAN,
                ..ON
            },
        ] {
            assert!(!DoNoHarmMonitor::new(bad, 100.0).is_on(), "{bad:?}");
        }
        let mut m = DoNoHarmMonitor::new(ON, 100.0);
        for _ in 0..100 {
            m.step(0.0, 1.0, 1.0);
        }
        let before = m;
        // A non-finite measurement is not scored; non-finite candidates not remembered.
        m.step(0.0, 1.0, f32::NAN);
        m.step(f32::INFINITY, 1.0, f32::NAN);
        m.step(0.0, f32::NAN, 1.0);
        assert_eq!(m.scores_nm2(), before.scores_nm2());
        assert_eq!(m.gain(), 1.0);
        // Huge values cannot make the statistics non-finite or the gain leave [0, 1].
        for _ in 0..10 {
            let out = m.step(0.0, 3.0e38, -3.0e38);
            assert!(
                (0.0..=1.0).contains(&m.gain()) && out.is_finite(),
                "{}",
                m.gain()
            );
        }
        let (a, b) = m.scores_nm2();
        assert!(a.is_finite() && b.is_finite());
    }
}
