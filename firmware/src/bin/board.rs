//! Board binary for the joint-drive MCU (STM32G474RE, Cortex-M4F, 170 MHz).
//!
//! Wires the library's control loop to the peripherals (register level, `stm32g4`
//! PAC); every register access lives in the `hw` module:
//! - TIM1: center-aligned PWM at 20 kHz on CH1..3 (PA8, PA9, PA10) with
//!   complementary outputs CH1N..3N (PB13, PB14, PB15), dead time, MOE as the
//!   bridge enable; CH4 (PWM mode 2, CCR4 = ARR - 1) drives TRGO at the counter's
//!   peak, where the low-side switches conduct.
//! - ADC1: three injected conversions triggered by TIM1 TRGO (phase currents a, b on
//!   PA0/IN1, PA1/IN2; bus voltage on PB1/IN12); the end-of-sequence interrupt
//!   (`ADC1_2`) is the PWM-rate control interrupt: it reads the encoder, runs
//!   `JointDrive::pwm_tick` and writes the three compare values.
//! - SPI1 (PA5 SCK, PA6 MISO, PA7 MOSI, PA4 chip select; mode 1, 5.3 MHz): the
//!   AS5047P encoder through `firmware::drivers::as5047p` (embedded-hal `SpiDevice`).
//! - USART3 (PB10 TX, PB11 RX, 2 Mbaud, FIFO): the state bus, standing in for
//!   EtherCAT; frames are `JointStateMessage::encode` (37 bytes, CRC-16), with a
//!   session number drawn from the RNG at every start.
//! - SysTick at `TICK_HZ`: the compensator tick (run in thread mode, so the LSTM's
//!   time never delays the PWM interrupt) and its DWT CYCCNT measurement.
//! - defmt over RTT (`--features board,defmt`): cycles (DWT CYCCNT, measured on the
//!   hardware) of the PWM tick and the compensator tick, faults, feedforward.
#![no_std]
#![no_main]
#![deny(unsafe_code)]

use core::cell::RefCell;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use cortex_m::interrupt::Mutex;
use cortex_m::peripheral::{DWT, syst::SystClkSource};
use cortex_m_rt::{ExceptionFrame, entry, exception};
use firmware::control::{
    BusClock, CascadeConfig, Compensator, CompensatorConfig, CurrentLoopConfig, DriveConfig,
    FaultFlags, FrameReceiver, JointDrive, JointReference, JointState, JointStateMessage,
    LstmPredictor, MotorParameters, SensorSample, StateLimits, SubsetModel,
};
use firmware::drivers::as5047p::{As5047p, counts_to_rad};
use firmware::dynamics::RigidBodyModel;
use firmware::model::default as compiled;
use heapless::Deque;
#[cfg(not(feature = "defmt"))]
use panic_halt as _;
use stm32g4::stm32g474::{self as pac, interrupt};
#[cfg(feature = "defmt")]
use {defmt_rtt as _, panic_probe as _};

/// The start-up copy of the CCM SRAM code (raw copy between linker-script
/// addresses).
#[path = "shared/ccm.rs"]
#[allow(unsafe_code)]
mod ccm;
/// The clock set-up shared with the bench binary (raw multi-bit `FLASH_ACR`,
/// `PLLCFGR` and `CFGR` field writes the PAC marks unsafe).
#[path = "shared/clock.rs"]
#[allow(unsafe_code)]
mod clock;
/// Core clock: HSI16 through the PLL (boost mode).
const CORE_CLOCK_HZ: u32 = clock::CORE_CLOCK_HZ;
/// Control tick rate (SysTick): the compensator tick, at the rate the compiled-in
/// network was trained for.
const TICK_HZ: u32 = compiled::CONTROL_RATE_HZ;
/// PWM frequency, Hz.
const PWM_HZ: u32 = 20_000;
/// TIM1 auto-reload for center-aligned PWM at `PWM_HZ`.
const PWM_ARR: u16 = (CORE_CLOCK_HZ / (2 * PWM_HZ)) as u16;
/// Compensated joints of the compiled-in model (the wrist: joints 4, 5, 6) and this
/// MCU's index among them.
const JOINTS: usize = compiled::JOINT_INDICES.len();
const OWN_JOINT: usize = 0;
/// Phase-current scale of the board's shunt amplifiers, A per ADC count, and
/// their zero (mid-scale).
const AMPS_PER_COUNT: f32 = 0.016_1;
const CURRENT_ZERO_COUNTS: f32 = 2048.0;
/// Bus-voltage divider, V per ADC count.
const VOLTS_PER_COUNT: f32 = 0.019_3;

/// The drive's configuration (motor and gear of the wrist joint).
fn drive_config() -> DriveConfig {
    DriveConfig {
        current: CurrentLoopConfig::tuned(MotorParameters::BOARD, PWM_HZ as f32),
        cascade: CascadeConfig {
            rate_hz: 5000.0,
            position_kp: 40.0,
            position_ki: 0.0,
            position_kd: 0.0,
            max_velocity_rad_s: 4.0,
            velocity_kp: 12.0,
            velocity_ki: 400.0,
            velocity_kd: 0.0,
            max_current_a: 15.0,
            velocity_filter_alpha: 0.3,
        },
        gear_ratio: 100.0,
        encoder_offset_rad: 0.0,
        max_current_a: 15.0,
        overcurrent_trip_a: 30.0,
        bus_min_v: 36.0,
        bus_max_v: 56.0,
        max_abs_q_ref_rad: 6.3,
    }
}

/// The compensator's configuration.
const COMPENSATOR_CONFIG: CompensatorConfig = CompensatorConfig {
    rate_hz: TICK_HZ as f32,
    own_joint: OWN_JOINT,
    state_limits: StateLimits {
        max_abs_q_rad: 6.3,
        max_abs_qd_rad_s: 5.0,
        max_abs_qdd_rad_s2: 200.0,
        max_abs_tau_nm: 300.0,
    },
    watchdog_ticks: 3,
    // The UART stand-in has no distributed clock: each sender's clock offset is
    // learned when its stream starts and followed within the two HSI16 oscillators'
    // tolerance (+-1 % each); a frame more than 3 ticks off that is stale.
    max_message_age_us: 3 * TICK_PERIOD_US,
    bus_clock: BusClock::FreeRunning {
        max_rate_error_ppm: 20_000,
    },
    max_torque_nm: 120.0,
    max_torque_rate_nm_s: 2_000.0,
    max_lstm_correction_nm: 30.0,
    warmup_ticks: 10,
    lstm_retry_ticks: 50,
    drive_gain_nm_per_a: 1.5 * 7.0 * 0.01 * 100.0,
    max_current_a: 12.0,
};
/// The compensator tick's period, microseconds.
const TICK_PERIOD_US: u32 = 1_000_000 / TICK_HZ;
// The sender-timestamp check is on: a few ticks, against each sender's clock.
const _: () = assert!(
    COMPENSATOR_CONFIG.max_message_age_us <= 5 * TICK_PERIOD_US
        && matches!(COMPENSATOR_CONFIG.bus_clock, BusClock::FreeRunning { .. })
);

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
    encoder: As5047p<hw::EncoderSpi>,
    pwm: hw::Pwm,
    adc: hw::Adc,
}

static PWM_CONTEXT: Mutex<RefCell<Option<PwmContext>>> = Mutex::new(RefCell::new(None));
/// Bus frames received by the USART interrupt, drained by the compensator tick.
static RX_MESSAGES: Mutex<RefCell<Deque<JointStateMessage, 8>>> =
    Mutex::new(RefCell::new(Deque::new()));
static RX_FRAMES: Mutex<RefCell<FrameReceiver>> = Mutex::new(RefCell::new(FrameReceiver::new()));
/// Feedforward current (f32 bits), written by the compensator, held by the PWM tick.
static FEEDFORWARD_A: AtomicU32 = AtomicU32::new(0);
/// The PWM tick's latest joint state (f32 bits) for the compensator and the bus.
static OWN_Q_RAD: AtomicU32 = AtomicU32::new(0);
static OWN_QD_RAD_S: AtomicU32 = AtomicU32::new(0);
static OWN_IQ_A: AtomicU32 = AtomicU32::new(0);
/// Faults of the PWM ticks since the last report.
static PWM_FAULTS: AtomicU32 = AtomicU32::new(0);
/// Longest PWM tick since the last report, cycles (DWT CYCCNT).
static PWM_TICK_MAX_CYCLES: AtomicU32 = AtomicU32::new(0);
/// Set by SysTick: a compensator tick is due.
static COMPENSATOR_DUE: AtomicBool = AtomicBool::new(false);

#[entry]
fn main() -> ! {
    ccm::copy_code();
    let (Some(mut cp), Some(dp)) = (cortex_m::Peripherals::take(), pac::Peripherals::take()) else {
        cortex_m::asm::udf();
    };
    cp.DCB.enable_trace();
    cp.DWT.enable_cycle_counter();
    let board = hw::init(dp, PWM_ARR);
    let mut bus = board.bus;
    let mut drive = JointDrive::new(drive_config());
    drive.set_position_origin(0.0);
    // Hold the start position until a trajectory master sends references.
    drive.set_reference(&JointReference::default());
    cortex_m::interrupt::free(|cs| {
        if let Ok(mut slot) = PWM_CONTEXT.borrow(cs).try_borrow_mut() {
            *slot = Some(PwmContext {
                drive,
                encoder: As5047p::new(board.encoder_spi),
                pwm: board.pwm,
                adc: board.adc,
            });
        }
    });
    // The LSTM stage: the compiled-in network in its preset's feature layout (with the
    // `drive` preset's linear stage).
    let Some(lstm) = LstmPredictor::<_, JOINTS, { compiled::INPUTS }>::new(
        &compiled::NETWORK,
        compiled::FEATURE_PRESET,
    ) else {
        cortex_m::asm::udf();
    };
    let lstm = lstm.with_linear_stage(compiled::LINEAR_STAGE);
    let Ok(mut compensator) = Compensator::<JOINTS, _, _>::new(COMPENSATOR_CONFIG, model(), lstm)
    else {
        cortex_m::asm::udf();
    };
    hw::start(&mut cp.NVIC);

    cp.SYST.set_clock_source(SystClkSource::Core);
    cp.SYST.set_reload(CORE_CLOCK_HZ / TICK_HZ - 1);
    cp.SYST.clear_current();
    cp.SYST.enable_interrupt();
    cp.SYST.enable_counter();
    firmware::fw_info!("board up: tick {=u32} Hz, PWM {=u32} Hz", TICK_HZ, PWM_HZ);

    let mut ticks: u32 = 0;
    let mut sequence: u16 = 0;
    let mut comp_cycles = firmware::log::TickStats::new();
    let mut comp_faults = FaultFlags::NONE;
    loop {
        if !COMPENSATOR_DUE.swap(false, Ordering::Acquire) {
            cortex_m::asm::wfi();
            continue;
        }
        let start = DWT::cycle_count();
        ticks = ticks.wrapping_add(1);
        let now_us = ticks.wrapping_mul(TICK_PERIOD_US);
        // Drain the bus (bounded by the queue's capacity).
        for _ in 0..8 {
            let Some(m) = cortex_m::interrupt::free(|cs| {
                RX_MESSAGES.borrow(cs).try_borrow_mut().ok()?.pop_front()
            }) else {
                break;
            };
            compensator.receive(&m);
        }
        let load = |a: &AtomicU32| f32::from_bits(a.load(Ordering::Relaxed));
        let own = JointState {
            q_ref_rad: 0.0,
            qd_ref_rad_s: 0.0,
            qdd_ref_rad_s2: 0.0,
            q_meas_rad: load(&OWN_Q_RAD),
            qd_meas_rad_s: load(&OWN_QD_RAD_S),
            tau_meas_nm: load(&OWN_IQ_A) * COMPENSATOR_CONFIG.drive_gain_nm_per_a,
        };
        let out = compensator.tick(&own, now_us);
        FEEDFORWARD_A.store(out.current_a.to_bits(), Ordering::Relaxed);
        // Tell the other joints our state.
        sequence = sequence.wrapping_add(1);
        let frame = JointStateMessage {
            joint: OWN_JOINT as u8,
            session: board.session,
            sequence,
            timestamp_us: now_us,
            state: own,
        }
        .encode();
        bus.send(&frame);
        let cycles = DWT::cycle_count().wrapping_sub(start);
        comp_cycles.record(cycles);
        comp_faults |= out.faults;
        if ticks.is_multiple_of(TICK_HZ) {
            let pwm_cycles = PWM_TICK_MAX_CYCLES.swap(0, Ordering::Relaxed);
            let pwm_faults = PWM_FAULTS.swap(0, Ordering::Relaxed);
            let comp = comp_cycles.take();
            firmware::fw_info!(
                "tick {=u32}: PWM tick max {=u32} cycles; compensator tick min/mean/max {=u32}/{=u32}/{=u32} cycles (DWT CYCCNT, measured); faults pwm {=u32:#06x} comp {=u16:#06x}; ff {=f32} A",
                ticks,
                pwm_cycles,
                comp.min_cycles,
                comp.mean_cycles(),
                comp.max_cycles,
                pwm_faults,
                comp_faults.bits(),
                out.current_a
            );
            let _ = (pwm_cycles, pwm_faults, comp);
            comp_faults = FaultFlags::NONE;
        }
    }
}

/// The compensator tick's clock (its DWT CYCCNT measurement is in `main`).
#[exception]
fn SysTick() {
    COMPENSATOR_DUE.store(true, Ordering::Release);
}

/// The PWM-rate control interrupt: ADC1 injected end of sequence (TIM1-triggered).
/// Runs from CCM SRAM (the section `ccm::copy_code` fills before interrupts are
/// enabled).
#[interrupt]
#[allow(unsafe_code)]
#[unsafe(link_section = ".ccmram_text")]
fn ADC1_2() {
    static mut CONTEXT: Option<PwmContext> = None;
    let start = DWT::cycle_count();
    if CONTEXT.is_none() {
        *CONTEXT =
            cortex_m::interrupt::free(|cs| PWM_CONTEXT.borrow(cs).try_borrow_mut().ok()?.take());
    }
    let Some(ctx) = CONTEXT.as_mut() else {
        return;
    };
    let raw = ctx.adc.read_injected_and_clear();
    let angle = match ctx.encoder.read_angle_counts() {
        Ok(c) => counts_to_rad(c),
        Err(_) => f32::NAN, // the drive flags SENSOR_INVALID and opens the bridge
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
    ctx.pwm.set_duties(out.duties, out.bridge_enabled);
    OWN_Q_RAD.store(out.q_rad.to_bits(), Ordering::Relaxed);
    OWN_QD_RAD_S.store(out.qd_rad_s.to_bits(), Ordering::Relaxed);
    OWN_IQ_A.store(out.iq_meas_a.to_bits(), Ordering::Relaxed);
    PWM_FAULTS.fetch_or(out.faults.bits() as u32, Ordering::Relaxed);
    let cycles = DWT::cycle_count().wrapping_sub(start);
    PWM_TICK_MAX_CYCLES.fetch_max(cycles, Ordering::Relaxed);
}

/// State-bus reception: bytes into frames into the queue (bounded per interrupt).
#[interrupt]
fn USART3() {
    for _ in 0..8 {
        let Some(byte) = hw::bus_read_byte() else {
            break;
        };
        cortex_m::interrupt::free(|cs| {
            let (Ok(mut rx), Ok(mut q)) = (
                RX_FRAMES.borrow(cs).try_borrow_mut(),
                RX_MESSAGES.borrow(cs).try_borrow_mut(),
            ) else {
                return;
            };
            if let Some(m) = rx.push(byte) {
                if q.is_full() {
                    let _ = q.pop_front();
                }
                let _ = q.push_back(m);
            }
        });
    }
}

/// Park the drive: the bridge outputs follow TIM1's break/idle state.
#[allow(unsafe_code)] // cortex-m-rt requires the handler to be `unsafe fn`
#[exception]
unsafe fn HardFault(_frame: &ExceptionFrame) -> ! {
    firmware::fw_error!("HardFault: pc={=u32:#x}", _frame.pc());
    loop {
        cortex_m::asm::bkpt();
    }
}

/// Register-level peripheral set-up and access (with `clock`, the binary's only
/// `unsafe`: raw multi-bit field writes the PAC marks unsafe, and byte-wide
/// SPI/USART data register access).
#[allow(unsafe_code)]
mod hw {
    use super::pac;
    use embedded_hal::spi::{ErrorKind, ErrorType, Operation, SpiDevice};

    /// Bound of every busy-wait, iterations.
    const SPIN_LIMIT: u32 = 100_000;

    fn spin_until(mut cond: impl FnMut() -> bool) -> bool {
        for _ in 0..SPIN_LIMIT {
            if cond() {
                return true;
            }
        }
        false
    }

    /// The configured peripherals.
    pub struct Board {
        pub pwm: Pwm,
        pub adc: Adc,
        pub encoder_spi: EncoderSpi,
        pub bus: Bus,
        /// This start's bus session number (from the RNG; 0 if it failed).
        pub session: u16,
    }

    /// Clocks, pins, TIM1, ADC1, SPI1, USART3.
    pub fn init(dp: pac::Peripherals, arr: u16) -> Board {
        let rcc = &dp.RCC;
        // 170 MHz: boost mode, 4 flash wait states, HSI16 / 4 * 85 / 2.
        let _ = super::clock::boost_170_mhz(rcc, &dp.PWR, &dp.FLASH);

        rcc.ahb2enr().modify(|_, w| {
            w.gpioaen()
                .set_bit()
                .gpioben()
                .set_bit()
                .adc12en()
                .set_bit()
        });
        rcc.apb2enr()
            .modify(|_, w| w.tim1en().set_bit().spi1en().set_bit());
        rcc.apb1enr1().modify(|_, w| w.usart3en().set_bit());

        // RNG (clocked by HSI48, CLK48SEL's reset value): one number for the bus
        // session, so that the other joints resynchronise after this board restarts.
        rcc.crrcr().modify(|_, w| w.hsi48on().set_bit());
        spin_until(|| rcc.crrcr().read().hsi48rdy().bit_is_set());
        rcc.ahb2enr().modify(|_, w| w.rngen().set_bit());
        dp.RNG.cr().modify(|_, w| w.rngen().set_bit());
        let session = if spin_until(|| dp.RNG.sr().read().drdy().bit_is_set()) {
            dp.RNG.dr().read().bits() as u16
        } else {
            0
        };
        dp.RNG.cr().modify(|_, w| w.rngen().clear_bit());

        // Pins. GPIOA: PA4 output (encoder chip select, high), PA5..7 AF5 (SPI1),
        // PA8..10 AF6 (TIM1 CH1..3). PA0, PA1 stay analog (reset state).
        let ga = &dp.GPIOA;
        ga.bsrr().write(|w| w.bs4().set_bit());
        ga.moder().modify(|_, w| unsafe {
            w.moder4()
                .bits(0b01)
                .moder5()
                .bits(0b10)
                .moder6()
                .bits(0b10)
                .moder7()
                .bits(0b10)
                .moder8()
                .bits(0b10)
                .moder9()
                .bits(0b10)
                .moder10()
                .bits(0b10)
        });
        ga.ospeedr().modify(|_, w| unsafe {
            w.ospeedr4()
                .bits(0b10)
                .ospeedr5()
                .bits(0b10)
                .ospeedr7()
                .bits(0b10)
                .ospeedr8()
                .bits(0b10)
                .ospeedr9()
                .bits(0b10)
                .ospeedr10()
                .bits(0b10)
        });
        ga.afrl()
            .modify(|_, w| unsafe { w.afrl5().bits(5).afrl6().bits(5).afrl7().bits(5) });
        ga.afrh()
            .modify(|_, w| unsafe { w.afrh8().bits(6).afrh9().bits(6).afrh10().bits(6) });
        // GPIOB: PB10/PB11 AF7 (USART3), PB13..15 AF6 (TIM1 CH1N..3N); PB1 analog.
        let gb = &dp.GPIOB;
        gb.moder().modify(|_, w| unsafe {
            w.moder10()
                .bits(0b10)
                .moder11()
                .bits(0b10)
                .moder13()
                .bits(0b10)
                .moder14()
                .bits(0b10)
                .moder15()
                .bits(0b10)
        });
        gb.ospeedr().modify(|_, w| unsafe {
            w.ospeedr13()
                .bits(0b10)
                .ospeedr14()
                .bits(0b10)
                .ospeedr15()
                .bits(0b10)
        });
        gb.afrh().modify(|_, w| unsafe {
            w.afrh10()
                .bits(7)
                .afrh11()
                .bits(7)
                .afrh13()
                .bits(6)
                .afrh14()
                .bits(6)
                .afrh15()
                .bits(6)
        });

        // TIM1: center-aligned PWM mode 1 on CH1..3 + complementary, 100 ns dead
        // time, CH4 in PWM mode 2 at ARR - 1 as TRGO (the counter's peak).
        let t = &dp.TIM1;
        t.psc().write(|w| unsafe { w.psc().bits(0) });
        t.arr().write(|w| unsafe { w.arr().bits(arr as u32) });
        t.cr1()
            .modify(|_, w| unsafe { w.cms().bits(0b01) }.arpe().set_bit());
        t.ccmr1_output().modify(|_, w| unsafe {
            w.oc1m()
                .bits(0b110)
                .oc1pe()
                .set_bit()
                .oc2m()
                .bits(0b110)
                .oc2pe()
                .set_bit()
        });
        t.ccmr2_output().modify(|_, w| unsafe {
            w.oc3m()
                .bits(0b110)
                .oc3pe()
                .set_bit()
                .oc4m()
                .bits(0b111)
                .oc4pe()
                .set_bit()
        });
        let half = arr as u32 / 2;
        t.ccr1().write(|w| unsafe { w.ccr().bits(half) });
        t.ccr2().write(|w| unsafe { w.ccr().bits(half) });
        t.ccr3().write(|w| unsafe { w.ccr().bits(half) });
        t.ccr4().write(|w| unsafe { w.ccr().bits(arr as u32 - 1) });
        t.ccer().modify(|_, w| {
            w.cc1e()
                .set_bit()
                .cc1ne()
                .set_bit()
                .cc2e()
                .set_bit()
                .cc2ne()
                .set_bit()
                .cc3e()
                .set_bit()
                .cc3ne()
                .set_bit()
        });
        t.bdtr().modify(|_, w| {
            unsafe { w.dtg().bits(17) }
                .ossr()
                .set_bit()
                .ossi()
                .set_bit()
        });
        t.cr2().modify(|_, w| unsafe { w.mms().bits(0b111) });
        t.egr().write(|w| w.ug().set_bit());

        // ADC1: synchronous clock HCLK/4, regulator, calibration, three injected
        // conversions on TIM1 TRGO rising edge, interrupt at end of sequence.
        dp.ADC12_COMMON
            .ccr()
            .modify(|_, w| unsafe { w.ckmode().bits(0b11) });
        let a = &dp.ADC1;
        a.cr().modify(|_, w| w.deeppwd().clear_bit());
        a.cr().modify(|_, w| w.advregen().set_bit());
        cortex_m::asm::delay(170 * 25);
        a.cr()
            .modify(|_, w| w.adcaldif().clear_bit().adcal().set_bit());
        spin_until(|| a.cr().read().adcal().bit_is_clear());
        cortex_m::asm::delay(100);
        a.isr().write(|w| w.adrdy().clear_bit_by_one());
        a.cr().modify(|_, w| w.aden().set_bit());
        spin_until(|| a.isr().read().adrdy().bit_is_set());
        a.smpr1()
            .modify(|_, w| unsafe { w.smp1().bits(0b010).smp2().bits(0b010) });
        a.smpr2().modify(|_, w| unsafe { w.smp12().bits(0b010) });
        a.jsqr().write(|w| unsafe {
            w.jl()
                .bits(2)
                .jextsel()
                .bits(0)
                .jexten()
                .bits(0b01)
                .jsq1()
                .bits(1)
                .jsq2()
                .bits(2)
                .jsq3()
                .bits(12)
        });
        a.ier().modify(|_, w| w.jeosie().set_bit());

        // SPI1: master, mode 1, 8-bit frames with the RX FIFO threshold at 8 bits,
        // software chip select, f_PCLK / 32.
        let s = &dp.SPI1;
        s.cr1().write(|w| {
            unsafe { w.br().bits(0b100) }
                .cpha()
                .set_bit()
                .mstr()
                .set_bit()
                .ssm()
                .set_bit()
                .ssi()
                .set_bit()
        });
        s.cr2()
            .write(|w| unsafe { w.ds().bits(0b0111) }.frxth().set_bit());
        s.cr1().modify(|_, w| w.spe().set_bit());

        // USART3: 2 Mbaud 8N1 with FIFO, receive interrupt.
        let u = &dp.USART3;
        u.brr()
            .write(|w| unsafe { w.bits(super::CORE_CLOCK_HZ / 2_000_000) });
        u.cr1().write(|w| {
            w.fifoen()
                .set_bit()
                .rxneie()
                .set_bit()
                .re()
                .set_bit()
                .te()
                .set_bit()
                .ue()
                .set_bit()
        });

        Board {
            pwm: Pwm { tim: dp.TIM1, arr },
            adc: Adc { adc: dp.ADC1 },
            encoder_spi: EncoderSpi {
                spi: dp.SPI1,
                gpio: dp.GPIOA,
            },
            bus: Bus { usart: dp.USART3 },
            session,
        }
    }

    /// Start the PWM timer, the injected conversions and the interrupts.
    pub fn start(nvic: &mut cortex_m::peripheral::NVIC) {
        // SAFETY: the peripherals were configured by `init`, which took ownership
        // of them; these are single-bit start writes and NVIC unmasking of
        // handlers that exist in this binary.
        let dp = unsafe { pac::Peripherals::steal() };
        dp.ADC1.cr().modify(|_, w| w.jadstart().set_bit());
        dp.TIM1.cr1().modify(|_, w| w.cen().set_bit());
        unsafe {
            nvic.set_priority(pac::Interrupt::ADC1_2, 0x10);
            nvic.set_priority(pac::Interrupt::USART3, 0x40);
            cortex_m::peripheral::NVIC::unmask(pac::Interrupt::ADC1_2);
            cortex_m::peripheral::NVIC::unmask(pac::Interrupt::USART3);
        }
    }

    /// TIM1's three PWM channels and the bridge enable (MOE).
    pub struct Pwm {
        tim: pac::TIM1,
        arr: u16,
    }

    impl Pwm {
        /// Write three duties in [0, 1] (preloaded: they apply from the next
        /// period) and switch the bridge on or off.
        pub fn set_duties(&mut self, duties: [f32; 3], enabled: bool) {
            let arr = self.arr as f32;
            // `as` saturates and maps NaN to 0.
            let c = duties.map(|d| (d * arr) as u32);
            self.tim.ccr1().write(|w| unsafe { w.ccr().bits(c[0]) });
            self.tim.ccr2().write(|w| unsafe { w.ccr().bits(c[1]) });
            self.tim.ccr3().write(|w| unsafe { w.ccr().bits(c[2]) });
            self.tim.bdtr().modify(|_, w| w.moe().bit(enabled));
        }
    }

    /// ADC1's injected channels.
    pub struct Adc {
        adc: pac::ADC1,
    }

    impl Adc {
        /// The three injected results (phase a, phase b, bus), and clear the flag.
        pub fn read_injected_and_clear(&mut self) -> [u16; 3] {
            let r = [
                self.adc.jdr1().read().jdata().bits(),
                self.adc.jdr2().read().jdata().bits(),
                self.adc.jdr3().read().jdata().bits(),
            ];
            self.adc.isr().write(|w| w.jeos().clear_bit_by_one());
            r
        }
    }

    /// SPI1 with PA4 as chip select: an embedded-hal 1.0 `SpiDevice` (chip select
    /// low for the whole transaction, bounded waits).
    pub struct EncoderSpi {
        spi: pac::SPI1,
        gpio: pac::GPIOA,
    }

    /// A busy-wait ran out (the bus is stuck).
    #[derive(Debug)]
    pub struct SpiTimeout;

    impl embedded_hal::spi::Error for SpiTimeout {
        fn kind(&self) -> ErrorKind {
            ErrorKind::Other
        }
    }

    impl ErrorType for EncoderSpi {
        type Error = SpiTimeout;
    }

    impl EncoderSpi {
        fn exchange(&mut self, out: u8) -> Result<u8, SpiTimeout> {
            let spi = &self.spi;
            if !spin_until(|| spi.sr().read().txe().bit_is_set()) {
                return Err(SpiTimeout);
            }
            // SAFETY: byte-wide access to the data register (a 16- or 32-bit
            // access would push two frames in 8-bit mode); the address is the
            // PAC's own.
            unsafe { core::ptr::write_volatile(spi.dr().as_ptr() as *mut u8, out) };
            if !spin_until(|| spi.sr().read().rxne().bit_is_set()) {
                return Err(SpiTimeout);
            }
            // SAFETY: as above, byte-wide read of the data register.
            Ok(unsafe { core::ptr::read_volatile(spi.dr().as_ptr() as *const u8) })
        }

        fn run(&mut self, op: &mut Operation<'_, u8>) -> Result<(), SpiTimeout> {
            match op {
                Operation::Read(buf) => {
                    for b in buf.iter_mut() {
                        *b = self.exchange(0)?;
                    }
                }
                Operation::Write(buf) => {
                    for &b in buf.iter() {
                        self.exchange(b)?;
                    }
                }
                Operation::Transfer(read, write) => {
                    for i in 0..read.len().max(write.len()) {
                        let r = self.exchange(write.get(i).copied().unwrap_or(0))?;
                        if let Some(slot) = read.get_mut(i) {
                            *slot = r;
                        }
                    }
                }
                Operation::TransferInPlace(buf) => {
                    for b in buf.iter_mut() {
                        *b = self.exchange(*b)?;
                    }
                }
                Operation::DelayNs(ns) => cortex_m::asm::delay(ns.saturating_mul(17) / 100 + 1),
            }
            Ok(())
        }
    }

    impl SpiDevice for EncoderSpi {
        fn transaction(&mut self, operations: &mut [Operation<'_, u8>]) -> Result<(), SpiTimeout> {
            self.gpio.bsrr().write(|w| w.br4().set_bit());
            // AS5047P: t_L (chip select low to first clock) >= 350 ns.
            cortex_m::asm::delay(60);
            let mut result = Ok(());
            for op in operations.iter_mut() {
                result = self.run(op);
                if result.is_err() {
                    break;
                }
            }
            let spi = &self.spi;
            spin_until(|| spi.sr().read().bsy().bit_is_clear());
            self.gpio.bsrr().write(|w| w.bs4().set_bit());
            // t_CSn (chip select high between frames) >= 350 ns.
            cortex_m::asm::delay(60);
            result
        }
    }

    /// USART3 transmit side of the state bus.
    pub struct Bus {
        usart: pac::USART3,
    }

    impl Bus {
        /// Send a frame (bounded wait per byte; a stuck bus drops the rest).
        pub fn send(&mut self, bytes: &[u8]) {
            let u = &self.usart;
            for &b in bytes {
                if !spin_until(|| u.isr().read().txe().bit_is_set()) {
                    return;
                }
                u.tdr().write(|w| unsafe { w.tdr().bits(b as u16) });
            }
        }
    }

    /// One received byte, if any (clears an overrun).
    pub fn bus_read_byte() -> Option<u8> {
        // SAFETY: only the USART3 interrupt reads RDR/ISR/ICR of USART3; thread
        // mode only writes TDR through `Bus`.
        let u = unsafe { pac::USART3::steal() };
        let isr = u.isr().read();
        if isr.ore().bit_is_set() {
            u.icr().write(|w| w.orecf().clear_bit_by_one());
        }
        if isr.rxne().bit_is_set() {
            Some(u.rdr().read().rdr().bits() as u8)
        } else {
            None
        }
    }
}
