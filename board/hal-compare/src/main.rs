//! The board binary's fast path and set-up on embassy-stm32 instead of the `stm32g4`
//! PAC, built only to measure the two against each other (README.md); not a product
//! binary and not run on hardware.
//!
//! Same as `board/src/main.rs`: the configuration page and `plan_startup`, 170 MHz
//! (HSI16 / 4 x 85 / 2, boost mode, 4 flash wait states, prefetch), TIM1
//! center-aligned complementary PWM at 20 kHz with 100 ns dead time, OC4REF at the
//! counter's peak triggering three ADC1 injected conversions (PA0, PA1, PB1), the
//! end-of-sequence interrupt `ADC1_2` in CCM SRAM reading the AS5047P over SPI1
//! (PA4 chip select), running `JointDrive::pwm_tick` and writing the three duties and
//! MOE; the compensator tick on SysTick in thread mode; the state bus on USART3; the
//! session number from the RNG. Each peripheral through embassy-stm32's own drivers:
//! `ComplementaryPwm`, `Adc::setup_injected_conversions` / `InjectedAdc`, blocking
//! `Spi` + `Output`, `BufferedUart`, `Rng`; the one register write embassy has no
//! API for is the flash prefetch enable (through embassy's own `pac`). With the
//! feature `register-fast-path` the interrupt's ADC reads and PWM writes go through
//! that `pac` too (the board's register accesses on embassy's set-up).
#![no_std]
#![no_main]
#![deny(unsafe_code)]

use core::cell::RefCell;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use cortex_m::interrupt::Mutex;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::{ExceptionFrame, entry, exception};
use embassy_stm32::adc::{Adc, AdcChannel, Exten, InjectedAdc, SampleTime};
use embassy_stm32::gpio::{Level, Output, OutputType, Speed};
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::peripherals::{ADC1, RNG, TIM1, USART3};
use embassy_stm32::spi::{self, Spi};
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::Channel;
use embassy_stm32::timer::complementary_pwm::{
    ComplementaryPwm, ComplementaryPwmPin, Mms2, Ossi, Ossr,
};
use embassy_stm32::timer::low_level::CountingMode;
use embassy_stm32::timer::simple_pwm::PwmPin;
use embassy_stm32::usart::{self, BufferedUart, BufferedUartRx, BufferedUartTx};
use embassy_stm32::{bind_interrupts, interrupt, rng};
use firmware::control::{
    BusClock, Compensator, FaultFlags, FrameReceiver, JointConfigBlock, JointDrive, JointProfile,
    JointReference, JointState, JointStateMessage, LstmPredictor, SensorSample, SubsetModel,
    plan_startup,
};
use firmware::drivers::as5047p::{As5047p, counts_to_rad};
use firmware::dynamics::RigidBodyModel;
use firmware::model::default as compiled;
use panic_halt as _;

mod encoder_spi;
use encoder_spi::EncoderSpi;

bind_interrupts!(struct Irqs {
    USART3 => usart::BufferedInterruptHandler<USART3>;
    RNG => rng::InterruptHandler<RNG>;
});

/// Core clock, Hz.
const CORE_CLOCK_HZ: u32 = 170_000_000;
/// Control tick rate (SysTick), the compiled-in model's.
const TICK_HZ: u32 = compiled::CONTROL_RATE_HZ;
/// PWM frequency, Hz.
const PWM_HZ: u32 = 20_000;
/// Dead time in TIM1 clock ticks (170 MHz): 17 = 100 ns, the board's DTG.
const DEAD_TIME_TICKS: u16 = 17;
/// Phase-current scale (the board's `adc::AMPS_PER_COUNT`), A per count.
const AMPS_PER_COUNT: f32 = 0.016_1;
/// Phase-current zero (mid-scale), ADC counts.
const CURRENT_ZERO_COUNTS: f32 = 2048.0;
/// Bus-voltage divider (the board's `adc::VOLTS_PER_COUNT`), V per count.
const VOLTS_PER_COUNT: f32 = 0.019_3;
/// Compensated joints of the compiled-in model.
const JOINTS: usize = compiled::JOINT_INDICES.len();
/// The compensator tick's period, microseconds.
const TICK_PERIOD_US: u32 = 1_000_000 / TICK_HZ;
/// Index in the compiled-in dynamics of each compensated joint.
const MODEL_JOINTS: [usize; JOINTS] =
    firmware::model::dynamics_indices(compiled::JOINT_INDICES, compiled::DYNAMICS_JOINTS);

fn model() -> SubsetModel<
    &'static RigidBodyModel<{ compiled::DYNAMICS_JOINTS }>,
    { compiled::DYNAMICS_JOINTS },
    JOINTS,
> {
    SubsetModel {
        model: &compiled::DYNAMICS,
        joints: MODEL_JOINTS,
        fixed_q_rad: [0.0; compiled::DYNAMICS_JOINTS],
    }
}

/// What the PWM interrupt owns.
struct PwmContext {
    drive: JointDrive,
    encoder: As5047p<EncoderSpi>,
    pwm: ComplementaryPwm<'static, TIM1>,
    /// The PWM's full-scale compare value (ARR), read once at set-up.
    max_duty: u32,
    adc: InjectedAdc<'static, ADC1, 3>,
}

static PWM_CONTEXT: Mutex<RefCell<Option<PwmContext>>> = Mutex::new(RefCell::new(None));
static FEEDFORWARD_A: AtomicU32 = AtomicU32::new(0);
static OWN_Q_RAD: AtomicU32 = AtomicU32::new(0);
static OWN_QD_RAD_S: AtomicU32 = AtomicU32::new(0);
static OWN_IQ_A: AtomicU32 = AtomicU32::new(0);
static PWM_FAULTS: AtomicU32 = AtomicU32::new(0);
static PWM_TICK_MAX_CYCLES: AtomicU32 = AtomicU32::new(0);
static COMPENSATOR_DUE: AtomicBool = AtomicBool::new(false);

#[allow(unsafe_code)]
mod placement {
    //! The start-up copy of `.ccmram_text` and the configuration page (as the board's
    //! `ccm` and `config_block` modules, on the board's `memory.x`).
    use firmware::control::JointConfigBlock;

    unsafe extern "C" {
        static mut __sccmram_text: u32;
        static mut __eccmram_text: u32;
        static __siccmram_text: u32;
        static __board_config: [u8; JointConfigBlock::LEN];
    }

    /// Copies `.ccmram_text` from its load image to CCM SRAM (first thing in `main`).
    pub fn copy_ccm_code() {
        // SAFETY: `memory.x` defines the section's run range in CCM SRAM (word
        // aligned, nothing else there) and its load image of the same length; none of
        // its code has run yet.
        unsafe {
            let start = &raw mut __sccmram_text;
            let end = &raw mut __eccmram_text;
            let words = (end as usize - start as usize) / 4;
            core::ptr::copy_nonoverlapping(&raw const __siccmram_text, start, words);
        }
        cortex_m::asm::dsb();
        cortex_m::asm::isb();
    }

    /// The configuration page's first 16 bytes.
    pub fn read_config_block() -> [u8; JointConfigBlock::LEN] {
        // SAFETY: `memory.x` places `__board_config` at the start of the BOARD_CONFIG
        // flash page, which the image never writes.
        unsafe { core::ptr::read_volatile(&raw const __board_config) }
    }
}

#[entry]
fn main() -> ! {
    placement::copy_ccm_code();
    let Some(mut cp) = cortex_m::Peripherals::take() else {
        cortex_m::asm::udf();
    };
    cp.DCB.enable_trace();
    cp.DWT.enable_cycle_counter();
    let config_bytes: [u8; JointConfigBlock::LEN] = placement::read_config_block();
    let plan = plan_startup(
        &config_bytes,
        &compiled::JOINT_INDICES,
        &compiled::JOINT_PROFILES,
        PWM_HZ as f32,
        TICK_HZ,
    );
    let joint = plan.joint.ok();
    let bus_baud = joint
        .and_then(|j| compiled::JOINT_PROFILES.get(j.slot))
        .map_or(JointProfile::BOARD.bus_baud, |p| p.bus_baud);

    // 170 MHz: HSI16 / 4 x 85 / 2, boost mode (embassy sets 4 wait states for it);
    // HSI48 for the RNG; the ADC kernel clock from SYSCLK (embassy divides it by 4:
    // 42.5 MHz, the board's HCLK / 4).
    let mut config = embassy_stm32::Config::default();
    {
        use embassy_stm32::rcc::*;
        config.rcc.pll = Some(Pll {
            source: PllSource::HSI,
            prediv: PllPreDiv::DIV4,
            mul: PllMul::MUL85,
            divp: None,
            divq: None,
            divr: Some(PllRDiv::DIV2),
        });
        config.rcc.sys = Sysclk::PLL1_R;
        config.rcc.boost = true;
        config.rcc.hsi48 = Some(Hsi48Config::default());
        config.rcc.mux.adc12sel = mux::Adcsel::SYS;
    }
    let p = embassy_stm32::init(config);
    // Prefetch on, as the board's clock module (embassy sets only the latency).
    embassy_stm32::pac::FLASH
        .acr()
        .modify(|w| w.set_prften(true));

    let session = {
        let mut rng = rng::Rng::new(p.RNG, Irqs);
        rng.next_u32() as u16
    };

    // TIM1: center-aligned, 20 kHz, CH1..3 + CH1N..3N, 100 ns dead time, bridge off;
    // CH4 at ARR - 1 and OC4REF as TRGO2: a rising edge at the counter's peak.
    let mut pwm = ComplementaryPwm::new(
        p.TIM1,
        Some(PwmPin::new(p.PA8, OutputType::PushPull)),
        Some(ComplementaryPwmPin::new(p.PB13, OutputType::PushPull)),
        Some(PwmPin::new(p.PA9, OutputType::PushPull)),
        Some(ComplementaryPwmPin::new(p.PB14, OutputType::PushPull)),
        Some(PwmPin::new(p.PA10, OutputType::PushPull)),
        Some(ComplementaryPwmPin::new(p.PB15, OutputType::PushPull)),
        None,
        None,
        Hertz::hz(PWM_HZ),
        CountingMode::CenterAlignedDownInterrupts,
    );
    pwm.set_master_output_enable(false);
    pwm.set_dead_time(DEAD_TIME_TICKS);
    pwm.set_off_state_selection_run(Ossr::IDLE_LEVEL);
    pwm.set_off_state_selection_idle(Ossi::IDLE_LEVEL);
    let max_duty = pwm.get_max_duty();
    for ch in [Channel::Ch1, Channel::Ch2, Channel::Ch3] {
        pwm.set_duty(ch, max_duty / 2);
        pwm.enable(ch);
    }
    pwm.set_duty(Channel::Ch4, max_duty - 1);
    pwm.set_mms2(Mms2::COMPARE_OC4);

    // ADC1: IN1 (PA0), IN2 (PA1), IN12 (PB1), 12.5 cycles each, on TIM1 TRGO2's rising
    // edge, end-of-sequence interrupt.
    let adc = Adc::new(p.ADC1, Default::default()).setup_injected_conversions(
        [
            (p.PA0.degrade_adc(), SampleTime::CYCLES12_5),
            (p.PA1.degrade_adc(), SampleTime::CYCLES12_5),
            (p.PB1.degrade_adc(), SampleTime::CYCLES12_5),
        ],
        embassy_stm32::triggers::TIM1_TRGO2,
        Exten::RISING_EDGE,
        true,
    );

    // SPI1 mode 1 at <= 5.3125 MHz (f_PCLK / 32), chip select PA4 idle high.
    let mut spi_config = spi::Config::default();
    spi_config.mode = spi::MODE_1;
    spi_config.frequency = Hertz(5_312_500);
    let spi = Spi::new_blocking(p.SPI1, p.PA5, p.PA7, p.PA6, spi_config);
    let chip_select = Output::new(p.PA4, Level::High, Speed::High);
    let encoder_spi = EncoderSpi::new(spi, chip_select);

    // USART3 at the profile's rate, interrupt-driven buffers.
    let mut bus_config = usart::Config::default();
    bus_config.baudrate = bus_baud;
    let (Some(tx_buffer), Some(rx_buffer)) = (
        cortex_m::singleton!(: [u8; 128] = [0; 128]),
        cortex_m::singleton!(: [u8; 256] = [0; 256]),
    ) else {
        cortex_m::asm::udf();
    };
    let Ok(bus) = BufferedUart::new(
        p.USART3, p.PB11, p.PB10, tx_buffer, rx_buffer, Irqs, bus_config,
    ) else {
        cortex_m::asm::udf();
    };
    let (mut bus_tx, mut bus_rx): (BufferedUartTx<'static>, BufferedUartRx<'static>) = bus.split();
    interrupt::USART3.set_priority(Priority::P4);

    if let Some(config) = plan.drive {
        let mut drive = JointDrive::new(config);
        drive.set_position_origin(0.0);
        drive.set_reference(&JointReference::default());
        cortex_m::interrupt::free(|cs| {
            if let Ok(mut slot) = PWM_CONTEXT.borrow(cs).try_borrow_mut() {
                *slot = Some(PwmContext {
                    drive,
                    encoder: As5047p::new(encoder_spi),
                    pwm,
                    max_duty,
                    adc,
                });
            }
        });
    }
    let Some(lstm) = LstmPredictor::<_, JOINTS, { compiled::INPUTS }>::new(
        &compiled::NETWORK,
        compiled::FEATURE_PRESET,
    ) else {
        cortex_m::asm::udf();
    };
    let lstm = lstm
        .with_linear_stage(compiled::LINEAR_STAGE)
        .with_envelope(compiled::ENVELOPE);
    let mut compensator = match plan.compensator {
        Some(config) => match Compensator::<JOINTS, _, _>::new(config, model(), lstm) {
            Ok(c) => Some(c),
            Err(_) => cortex_m::asm::udf(),
        },
        None => None,
    };
    if plan.drive.is_some() {
        interrupt::ADC1_2.set_priority(Priority::P1);
        #[allow(unsafe_code)]
        // SAFETY: the handler's context is in place; no critical section is open.
        unsafe {
            interrupt::ADC1_2.enable()
        };
    }
    cp.SYST.set_clock_source(SystClkSource::Core);
    cp.SYST.set_reload(CORE_CLOCK_HZ / TICK_HZ - 1);
    cp.SYST.clear_current();
    cp.SYST.enable_interrupt();
    cp.SYST.enable_counter();
    let drive_gain_nm_per_a = plan.compensator.map_or(0.0, |c| c.drive_gain_nm_per_a);

    let mut frames = FrameReceiver::new();
    let mut ticks: u32 = 0;
    let mut sequence: u16 = 0;
    let mut comp_cycles = firmware::log::TickStats::new();
    let mut comp_faults = FaultFlags::NONE;
    loop {
        if !COMPENSATOR_DUE.swap(false, Ordering::Acquire) {
            cortex_m::asm::wfi();
            continue;
        }
        let start = cortex_m::peripheral::DWT::cycle_count();
        ticks = ticks.wrapping_add(1);
        let now_us = ticks.wrapping_mul(TICK_PERIOD_US);
        // Drain the bus's receive buffer (bounded by its size).
        for _ in 0..256 {
            let Ok(byte) = embedded_hal_nb::serial::Read::read(&mut bus_rx) else {
                break;
            };
            if let (Some(m), Some(c)) = (frames.push(byte), compensator.as_mut()) {
                c.receive(&m);
            }
        }
        let load = |a: &AtomicU32| f32::from_bits(a.load(Ordering::Relaxed));
        let own = JointState {
            q_ref_rad: 0.0,
            qd_ref_rad_s: 0.0,
            qdd_ref_rad_s2: 0.0,
            q_meas_rad: load(&OWN_Q_RAD),
            qd_meas_rad_s: load(&OWN_QD_RAD_S),
            tau_meas_nm: load(&OWN_IQ_A) * drive_gain_nm_per_a,
        };
        let (Some(c), Some(j)) = (compensator.as_mut(), joint) else {
            continue;
        };
        let out = c.tick(&own, now_us);
        FEEDFORWARD_A.store(out.current_a.to_bits(), Ordering::Relaxed);
        sequence = sequence.wrapping_add(1);
        let frame = JointStateMessage {
            joint: j.slot as u8,
            session,
            sequence,
            timestamp_us: now_us,
            state: own,
        }
        .encode();
        let _ = embedded_io::Write::write(&mut bus_tx, &frame);
        comp_cycles.record(cortex_m::peripheral::DWT::cycle_count().wrapping_sub(start));
        comp_faults |= out.faults;
        if ticks.is_multiple_of(TICK_HZ) {
            let _ = (
                PWM_TICK_MAX_CYCLES.swap(0, Ordering::Relaxed),
                PWM_FAULTS.swap(0, Ordering::Relaxed),
                comp_cycles.take(),
            );
            comp_faults = FaultFlags::NONE;
        }
    }
}

// Every compensated joint's sender-timestamp check is on (as the board requires).
const _: () = {
    let mut k = 0;
    while k < JOINTS {
        let c = compiled::JOINT_PROFILES[k].compensator_config(TICK_HZ, k);
        assert!(
            c.max_message_age_us <= 5 * TICK_PERIOD_US
                && matches!(c.bus_clock, BusClock::FreeRunning { .. })
        );
        k += 1;
    }
};

#[exception]
fn SysTick() {
    COMPENSATOR_DUE.store(true, Ordering::Release);
}

/// The PWM-rate control interrupt: ADC1 injected end of sequence (TIM1-triggered),
/// from CCM SRAM; the same body as the board's, on embassy's drivers.
#[interrupt]
#[allow(unsafe_code)]
#[unsafe(link_section = ".ccmram_text")]
fn ADC1_2() {
    static mut CONTEXT: Option<PwmContext> = None;
    let start = cortex_m::peripheral::DWT::cycle_count();
    if CONTEXT.is_none() {
        *CONTEXT =
            cortex_m::interrupt::free(|cs| PWM_CONTEXT.borrow(cs).try_borrow_mut().ok()?.take());
    }
    let Some(ctx) = CONTEXT.as_mut() else {
        return;
    };
    let raw = read_injected(&mut ctx.adc);
    let angle = match ctx.encoder.read_angle_counts() {
        Ok(c) => counts_to_rad(c),
        Err(_) => f32::NAN,
    };
    let sample = SensorSample {
        phase_current_a: [
            (raw[0] as f32 - CURRENT_ZERO_COUNTS) * AMPS_PER_COUNT,
            (raw[1] as f32 - CURRENT_ZERO_COUNTS) * AMPS_PER_COUNT,
        ],
        motor_angle_rad: angle,
        bus_v: raw[2] as f32 * VOLTS_PER_COUNT,
    };
    ctx.drive
        .set_feedforward_current(f32::from_bits(FEEDFORWARD_A.load(Ordering::Relaxed)));
    let out = ctx.drive.pwm_tick(&sample);
    write_duties(&mut ctx.pwm, ctx.max_duty, out.duties, out.bridge_enabled);
    OWN_Q_RAD.store(out.q_rad.to_bits(), Ordering::Relaxed);
    OWN_QD_RAD_S.store(out.qd_rad_s.to_bits(), Ordering::Relaxed);
    OWN_IQ_A.store(out.iq_meas_a.to_bits(), Ordering::Relaxed);
    PWM_FAULTS.fetch_or(out.faults.bits(), Ordering::Relaxed);
    let cycles = cortex_m::peripheral::DWT::cycle_count().wrapping_sub(start);
    PWM_TICK_MAX_CYCLES.fetch_max(cycles, Ordering::Relaxed);
}

/// The three injected results, and the end-of-sequence flag cleared: embassy's
/// `InjectedAdc::read_injected_samples`.
#[cfg(not(feature = "register-fast-path"))]
#[inline(always)]
fn read_injected(adc: &mut InjectedAdc<'static, ADC1, 3>) -> [u16; 3] {
    adc.read_injected_samples()
}

/// The three injected results, and the end-of-sequence flag cleared: the registers
/// through embassy's `pac`, as the board's `Adc::read_injected_and_clear`.
#[cfg(feature = "register-fast-path")]
#[inline(always)]
fn read_injected(_adc: &mut InjectedAdc<'static, ADC1, 3>) -> [u16; 3] {
    let adc = embassy_stm32::pac::ADC1;
    let raw = [0, 1, 2].map(|i| adc.jdr(i).read().jdata());
    adc.isr().write(|w| w.set_jeos(true));
    raw
}

/// Three duties in [0, 1] and the bridge enable: embassy's `ComplementaryPwm`.
#[cfg(not(feature = "register-fast-path"))]
#[inline(always)]
fn write_duties(
    pwm: &mut ComplementaryPwm<'static, TIM1>,
    max_duty: u32,
    duties: [f32; 3],
    enabled: bool,
) {
    // `as` saturates and maps NaN to 0; the clamp keeps `set_duty`'s range check true.
    let full = max_duty as f32;
    let c = duties.map(|d| ((d * full) as u32).min(max_duty));
    pwm.set_duty(Channel::Ch1, c[0]);
    pwm.set_duty(Channel::Ch2, c[1]);
    pwm.set_duty(Channel::Ch3, c[2]);
    pwm.set_master_output_enable(enabled);
}

/// Three duties in [0, 1] and the bridge enable: TIM1's compare registers and MOE
/// through embassy's `pac`, as the board's `Pwm::set_duties`.
#[cfg(feature = "register-fast-path")]
#[inline(always)]
fn write_duties(
    _pwm: &mut ComplementaryPwm<'static, TIM1>,
    max_duty: u32,
    duties: [f32; 3],
    enabled: bool,
) {
    let tim = embassy_stm32::pac::TIM1;
    let full = max_duty as f32;
    let c = duties.map(|d| (d * full) as u16);
    tim.ccr(0).write(|w| w.set_ccr(c[0]));
    tim.ccr(1).write(|w| w.set_ccr(c[1]));
    tim.ccr(2).write(|w| w.set_ccr(c[2]));
    tim.bdtr().modify(|w| w.set_moe(enabled));
}

/// Park the drive: the bridge outputs follow TIM1's break/idle state.
#[allow(unsafe_code)]
#[exception]
unsafe fn HardFault(_frame: &ExceptionFrame) -> ! {
    loop {
        cortex_m::asm::bkpt();
    }
}
