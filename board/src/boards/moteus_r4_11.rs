//! mjbots moteus r4.11 (STM32G474CEU6, DRV8353 gate driver, on-board AS5047P,
//! CAN-FD). Facts from mjbots/moteus (public, Apache-2.0), file and line in
//! `board/README.md` ("moteus r4.11: where each pin comes from"); written here, not
//! copied. Family 0, hardware revision r4.11 (`fw/moteus_hw.cc` `FindHardwarePins`,
//! the `hv >= 5` branches).

use super::Function::{Alternate, Analog, Input, Output};
use super::{Assignment, BoardPins, Bridge, Port::*, Pull, pin};

const fn af(peripheral: &'static str, signal: &'static str, af: u8) -> super::Function {
    Alternate {
        peripheral,
        signal,
        af,
    }
}

/// moteus r4.11.
#[rustfmt::skip]
pub const BOARD: BoardPins = BoardPins {
    name: "moteus-r4-11",
    chip: "STM32G474CE",
    bridge: Bridge::GateDriverThreeInputs { timer: "TIM5" },
    pins: &[
        // Gate driver inputs INHA..C (3-input mode): PA0..2 "ALT0" = TIM5 CH1..3.
        Assignment { pin: pin(A, 0), function: af("TIM5", "CH1", 2), role: "phase a PWM" },
        Assignment { pin: pin(A, 1), function: af("TIM5", "CH2", 2), role: "phase b PWM" },
        Assignment { pin: pin(A, 2), function: af("TIM5", "CH3", 2), role: "phase c PWM" },
        // Gate driver control: ENABLE, HIZ (held low: no high-impedance request),
        // chip select; nFAULT is open drain (pull-up).
        Assignment { pin: pin(A, 3), function: Output { idle_high: false }, role: "gate driver enable" },
        Assignment { pin: pin(B, 7), function: Output { idle_high: false }, role: "gate driver hiz" },
        Assignment { pin: pin(C, 4), function: Output { idle_high: true }, role: "gate driver chip select" },
        Assignment { pin: pin(B, 6), function: Input { pull: Pull::Up }, role: "gate driver nFAULT" },
        // SPI1 shared by the gate driver and the encoder (both SPI mode 1).
        Assignment { pin: pin(A, 5), function: af("SPI1", "SCK", 5), role: "SPI1 SCK" },
        Assignment { pin: pin(A, 6), function: af("SPI1", "MISO", 5), role: "SPI1 MISO" },
        Assignment { pin: pin(A, 7), function: af("SPI1", "MOSI", 5), role: "SPI1 MOSI" },
        Assignment { pin: pin(B, 11), function: Output { idle_high: true }, role: "encoder chip select" },
        // Phase currents on three ADCs (sampled together), bus voltage, motor
        // temperature sense.
        Assignment { pin: pin(B, 0), function: Analog { peripheral: "ADC3", signal: "IN12" }, role: "phase a current" },
        Assignment { pin: pin(B, 1), function: Analog { peripheral: "ADC1", signal: "IN12" }, role: "phase b current" },
        Assignment { pin: pin(B, 2), function: Analog { peripheral: "ADC2", signal: "IN12" }, role: "phase c current" },
        Assignment { pin: pin(B, 12), function: Analog { peripheral: "ADC4", signal: "IN3" }, role: "bus voltage" },
        Assignment { pin: pin(A, 8), function: Analog { peripheral: "ADC5", signal: "IN1" }, role: "motor temperature" },
        Assignment { pin: pin(A, 9), function: Analog { peripheral: "ADC5", signal: "IN2" }, role: "board temperature" },
        // CAN-FD transceiver.
        Assignment { pin: pin(A, 12), function: af("FDCAN1", "TX", 9), role: "CAN TX" },
        Assignment { pin: pin(A, 11), function: af("FDCAN1", "RX", 9), role: "CAN RX" },
        // LEDs.
        Assignment { pin: pin(F, 0), function: Output { idle_high: false }, role: "debug LED" },
        Assignment { pin: pin(F, 1), function: Output { idle_high: false }, role: "power LED" },
    ],
};

/// Bus-voltage divider scale for r4.6 and later, V per volt at the pin
/// (`fw/moteus_hw.cc`: `vsense_adc_scale` 0.017947 for `hv > 5`; moteus multiplies
/// the 12-bit count by it after scaling to 3.3 V full scale; check on the board).
pub const VSENSE_ADC_SCALE: f32 = 0.017947;

/// The gate driver's settings: mjbots' defaults for family 0, hardware revision 8
/// (`fw/drv8323.h` `Config`): 3-input PWM, OCP_ACT, gate currents 100 / 200 mA
/// (high side) and 100 / 600 mA (low side), TDRIVE 1000 ns, cycle-by-cycle, dead
/// time 50 ns, latched overcurrent fault, 4 µs deglitch, VDS level 700 mV, sense
/// amplifiers bidirectional (VREF / 2) at 20 V/V, sense overcurrent 0.5 V.
pub const GATE_DRIVER: firmware::drivers::drv83x3::Config = {
    use firmware::drivers::drv83x3::*;
    Config {
        driver_control: DriverControl {
            ocp_act: true,
            dis_cpuv: false,
            dis_gdf: false,
            otw_rep: false,
            pwm_mode: PwmMode::ThreeInput,
            pwm1_com: false,
            pwm1_dir: false,
            coast: false,
            brake: false,
            clr_flt: false,
        },
        gate_drive_hs: GateDriveHs {
            idrivep: Code4::at_least(&idrive_ma::DRV8353_SOURCE, 100),
            idriven: Code4::at_least(&idrive_ma::DRV8353_SINK, 200),
        },
        gate_drive_ls: GateDriveLs {
            cbc: true,
            tdrive: Tdrive::Ns1000,
            idrivep: Code4::at_least(&idrive_ma::DRV8353_SOURCE, 100),
            idriven: Code4::at_least(&idrive_ma::DRV8353_SINK, 600),
        },
        ocp_control: OcpControl {
            tretry_short: false,
            dead_time: DeadTime::Ns50,
            ocp_mode: OcpMode::LatchedFault,
            // DRV8353 deglitch codes: 1, 2, 4, 8 µs.
            ocp_deg: 2,
            // DRV8353 VDS_LVL code 10: 0.7 V.
            vds_lvl: Code4::at_least(&vds_lvl_mv::DRV8353, 700),
        },
        csa_control: CsaControl {
            csa_fet: false,
            vref_div: true,
            ls_ref: false,
            gain: CsaGain::X20,
            dis_sen: false,
            cal: [false; 3],
            sen_lvl: 1,
        },
    }
};
