//! QEMU test binary (mps2-an386, Cortex-M4F): runs the firmware's numeric code on
//! golden inputs and prints every result over semihosting for `host-tests` to
//! compare bit for bit with the host. Exits through semihosting: success after
//! `@pass`, failure on panic or HardFault.
#![no_std]
#![no_main]

use core::fmt::Write;
use cortex_m_rt::entry;
use cortex_m_semihosting::hio;
use test_kit::fixtures::GoldenModel;
use test_kit::golden::network::STEPS;
use test_kit::golden::{self, MathFn};

mod exit;
/// The start-up copy of the CCM SRAM code, as on the board.
use board_ccm as ccm;
use exit::{fail, pass};

/// Line-buffered semihosting writer: one host call per ~1 KiB, not per line.
struct Report {
    buf: heapless::String<1024>,
    host: hio::HostStream,
}

impl Report {
    fn new() -> Self {
        let host = match hio::hstdout() {
            Ok(h) => h,
            Err(()) => fail(),
        };
        Report {
            buf: heapless::String::new(),
            host,
        }
    }

    fn line(&mut self, args: core::fmt::Arguments) {
        if self.buf.len() > 900 {
            self.flush();
        }
        if self.buf.write_fmt(args).is_err() || self.buf.push('\n').is_err() {
            fail();
        }
    }

    fn flush(&mut self) {
        if self.host.write_all(self.buf.as_bytes()).is_err() {
            fail();
        }
        self.buf.clear();
    }
}

#[entry]
fn main() -> ! {
    ccm::copy_code();
    let mut out = Report::new();

    out.line(format_args!("@suite math {}", golden::MATH_POINTS));
    for f in MathFn::ALL {
        for i in 0..golden::MATH_POINTS {
            let x = f.input(i);
            let y = f.eval(x);
            out.line(format_args!(
                "{} {} {:08x} {:08x}",
                f.name(),
                i,
                x.to_bits(),
                y.to_bits()
            ));
        }
    }
    out.line(format_args!("@end math"));

    out.line(format_args!("@suite dot {}", golden::DOT_CASES));
    for case in 0..golden::DOT_CASES {
        let y = golden::dot_output(case);
        out.line(format_args!(
            "dot {} {:08x} {:08x}",
            case,
            case as u32,
            y.to_bits()
        ));
    }
    out.line(format_args!("@end dot"));

    out.line(format_args!("@suite cells {}", 10 * golden::CELL_CASES));
    let (c, h, t, m) = golden::cells_output();
    for j in 0..golden::CELL_CASES {
        out.line(format_args!("c {} {:08x} {:08x}", j, j as u32, c[j].to_bits()));
        out.line(format_args!("h {} {:08x} {:08x}", j, j as u32, h[j].to_bits()));
        for r in 0..4 {
            let k = 4 * j + r;
            out.line(format_args!("t {} {:08x} {:08x}", k, k as u32, t[j][r].to_bits()));
            out.line(format_args!("m {} {:08x} {:08x}", k, k as u32, m[j][r].to_bits()));
        }
    }
    out.line(format_args!("@end cells"));

    out.line(format_args!(
        "@suite features {}",
        golden::FEATURE_CASES * golden::FEATURE_VALUES
    ));
    for case in 0..golden::FEATURE_CASES {
        for (k, v) in golden::feature_output(case).iter().enumerate() {
            out.line(format_args!(
                "f{} {} {:08x} {:08x}",
                k,
                case,
                case as u32,
                v.to_bits()
            ));
        }
    }
    out.line(format_args!("@end features"));

    out.line(format_args!(
        "@suite monitor {}",
        golden::MONITOR_CASES * golden::MONITOR_VALUES
    ));
    for case in 0..golden::MONITOR_CASES {
        for (k, v) in golden::monitor_output(case).iter().enumerate() {
            out.line(format_args!(
                "m{} {} {:08x} {:08x}",
                k,
                case,
                case as u32,
                v.to_bits()
            ));
        }
    }
    out.line(format_args!("@end monitor"));

    out.line(format_args!(
        "@suite dynamics {}",
        golden::DYNAMICS_CASES * golden::DYNAMICS_JOINTS
    ));
    let model = golden::dynamics_model();
    for case in 0..golden::DYNAMICS_CASES {
        let tau = golden::dynamics_output(&model, case);
        for (j, t) in tau.iter().enumerate() {
            out.line(format_args!(
                "tau{} {} {:08x} {:08x}",
                j + 1,
                case,
                case as u32,
                t.to_bits()
            ));
        }
    }
    out.line(format_args!("@end dynamics"));

    out.line(format_args!(
        "@suite lstm {}",
        golden::LSTM_STEPS * golden::LSTM_O
    ));
    golden::lstm_stream(|t, y| {
        for (k, v) in y.iter().enumerate() {
            out.line(format_args!(
                "lstm {} {:08x} {:08x}",
                t * golden::LSTM_O + k,
                t as u32,
                v.to_bits()
            ));
        }
    });
    out.line(format_args!("@end lstm"));

    out.line(format_args!(
        "@suite envelope {}",
        golden::ENVELOPE_CASES * golden::ENVELOPE_VALUES + 4 * golden::ENVELOPE_STEPS
    ));
    for case in 0..golden::ENVELOPE_CASES {
        for (k, v) in golden::envelope_output(case).iter().enumerate() {
            out.line(format_args!(
                "e{} {} {:08x} {:08x}",
                k,
                case,
                case as u32,
                v.to_bits()
            ));
        }
    }
    golden::envelope_stream(|t, y, w| {
        out.line(format_args!("ey {} {:08x} {:08x}", t, t as u32, y.to_bits()));
        out.line(format_args!("ew {} {:08x} {:08x}", t, t as u32, w.to_bits()));
    });
    out.line(format_args!("@end envelope"));

    // The compiled-in model's compensator on the envelope proof's fast motion
    // (test_kit::proof; records only for a single-joint `drive` model): each tick's
    // output (`py`) and fault flags (`pf`).
    {
        use firmware::model::default as m;
        let mut n = 0usize;
        let run = |emit: &mut dyn FnMut(usize, test_kit::proof::ProofTick)| {
            test_kit::proof::stream::<{ m::OUTPUTS }, { m::INPUTS }, _>(
                &m::NETWORK,
                m::FEATURE_PRESET,
                m::LINEAR_STAGE,
                m::ENVELOPE,
                &m::JOINT_PROFILES[0],
                test_kit::proof::FAST_SPEED,
                test_kit::proof::FAST_PHASE_RAD,
                test_kit::proof::FAST_TICKS,
                emit,
            )
        };
        run(&mut |_, _| n += 1);
        out.line(format_args!("@suite proof {}", 2 * n));
        run(&mut |k, t| {
            out.line(format_args!(
                "py {} {:08x} {:08x}",
                k,
                k as u32,
                t.output_nm.to_bits()
            ));
            out.line(format_args!("pf {} {:08x} {:08x}", k, k as u32, t.faults));
        });
        out.line(format_args!("@end proof"));
    }

    // Network kernels (firmware::nn::kernels): 10 000 streaming steps of each golden model.
    for g in GoldenModel::ALL {
        let n = g.outputs();
        out.line(format_args!("@suite {} {}", g.name(), STEPS * n));
        g.stream(STEPS, &mut |t, y| {
            for (k, v) in y.iter().enumerate() {
                out.line(format_args!(
                    "{} {} {:08x} {:08x}",
                    g.name(),
                    t * n + k,
                    t as u32,
                    v.to_bits()
                ));
            }
        });
        out.line(format_args!("@end {}", g.name()));
    }

    out.line(format_args!("@pass"));
    out.flush();
    pass()
}
