//! Every board's pin map against the STM32G474's own data (`stm32-metapac` metadata
//! for the STM32G474CE, the 48-pin package moteus uses: a pin found there exists in
//! every larger G474 package too, so the generic 64-pin board's map is held to the
//! same, stricter, list): each pin exists in the package, each alternate function
//! number is the one that carries the named peripheral signal on that pin, each
//! analog input is that ADC's channel on that pin, and no pin is used twice. A map
//! with one wrong AF, a missing pin or a doubled pin is rejected (shown below).

use board::boards::{ALL, Assignment, BoardPins, Function, Port, pin};
use stm32_metapac::metadata::{METADATA, Metadata};

fn name(a: &Assignment) -> String {
    format!("P{}{}", a.pin.port.letter(), a.pin.number)
}

/// Every problem of `map` against `chip`, one line each (empty: the map is right).
fn check(map: &[Assignment], chip: &Metadata) -> Vec<String> {
    let mut errors = Vec::new();
    for (i, a) in map.iter().enumerate() {
        let pin = name(a);
        if a.pin.number > 15 || !chip.pins.iter().any(|p| p.name == pin) {
            errors.push(format!("{pin} ({}): not a pin of {}", a.role, chip.name));
            continue;
        }
        if let Some(first) = map[..i].iter().find(|b| b.pin == a.pin) {
            errors.push(format!(
                "{pin} ({}): already used for {}",
                a.role, first.role
            ));
        }
        let (peripheral, signal, af) = match a.function {
            Function::Alternate {
                peripheral,
                signal,
                af,
            } => (peripheral, signal, Some(af)),
            Function::Analog { peripheral, signal } => (peripheral, signal, None),
            Function::Output { .. } | Function::Input { .. } => continue,
        };
        let Some(p) = chip.peripherals.iter().find(|p| p.name == peripheral) else {
            errors.push(format!(
                "{pin} ({}): no peripheral {peripheral} on {}",
                a.role, chip.name
            ));
            continue;
        };
        let on_pin: Vec<_> = p.pins.iter().filter(|pp| pp.pin == pin).collect();
        match on_pin.iter().find(|pp| pp.signal == signal) {
            None => errors.push(format!(
                "{pin} ({}): {peripheral} {signal} is not on this pin (it carries {:?})",
                a.role,
                on_pin.iter().map(|pp| pp.signal).collect::<Vec<_>>()
            )),
            Some(pp) if pp.af != af => errors.push(format!(
                "{pin} ({}): {peripheral} {signal} is AF {:?} on this pin, the map says {:?}",
                a.role, pp.af, af
            )),
            Some(_) => {}
        }
    }
    errors
}

fn board(name: &str) -> &'static BoardPins {
    ALL.iter().find(|b| b.name == name).copied().unwrap()
}

#[test]
fn metadata_is_the_g474() {
    assert_eq!(METADATA.name, "STM32G474CE");
    assert!(METADATA.pins.len() >= 38, "{} pins", METADATA.pins.len());
}

#[test]
fn every_board_map_matches_the_chip() {
    for b in ALL {
        let errors = check(b.pins, &METADATA);
        assert!(errors.is_empty(), "{}:\n{}", b.name, errors.join("\n"));
        assert!(b.chip.starts_with("STM32G474"), "{}", b.chip);
        println!(
            "{}: {} pins checked against {}",
            b.name,
            b.pins.len(),
            METADATA.name
        );
    }
}

#[test]
fn the_moteus_image_drives_a_gate_driver_and_reads_its_encoder() {
    let m = board("moteus-r4-11");
    for role in [
        "gate driver enable",
        "gate driver chip select",
        "gate driver nFAULT",
        "encoder chip select",
        "SPI1 SCK",
        "phase a PWM",
        "CAN TX",
    ] {
        assert!(m.by_role(role).is_some(), "moteus r4.11 has no {role}");
    }
}

#[test]
fn a_wrong_af_is_rejected() {
    let m = board("moteus-r4-11");
    // TIM5 CH1 is AF2 on PA0; TIM2 CH1 is AF1 there: a map saying AF1 for TIM5 is wrong.
    let mut wrong: Vec<Assignment> = m.pins.to_vec();
    let i = wrong.iter().position(|a| a.role == "phase a PWM").unwrap();
    wrong[i].function = Function::Alternate {
        peripheral: "TIM5",
        signal: "CH1",
        af: 1,
    };
    let errors = check(&wrong, &METADATA);
    println!("{errors:?}");
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert!(
        errors[0].starts_with("PA0 (phase a PWM): TIM5 CH1 is AF Some(2)"),
        "{errors:?}"
    );

    // Every AF of every alternate-function pin, off by one either way, is caught.
    for b in ALL {
        for (i, a) in b.pins.iter().enumerate() {
            if let Function::Alternate {
                peripheral,
                signal,
                af,
            } = a.function
            {
                for bad in [af.wrapping_add(1) & 15, af.wrapping_sub(1) & 15] {
                    let mut m: Vec<Assignment> = b.pins.to_vec();
                    m[i].function = Function::Alternate {
                        peripheral,
                        signal,
                        af: bad,
                    };
                    assert!(
                        !check(&m, &METADATA).is_empty(),
                        "{} {}: AF {bad} passed",
                        b.name,
                        a.role
                    );
                }
            }
        }
    }
}

#[test]
fn a_wrong_signal_missing_pin_or_double_use_is_rejected() {
    let g = board("generic");
    // SPI1 MOSI is not on PA6 (it is MISO there).
    let mut m: Vec<Assignment> = g.pins.to_vec();
    let i = m.iter().position(|a| a.role == "encoder MISO").unwrap();
    m[i].function = Function::Alternate {
        peripheral: "SPI1",
        signal: "MOSI",
        af: 5,
    };
    assert_eq!(check(&m, &METADATA).len(), 1);
    // An ADC channel on the wrong pin.
    let mut m: Vec<Assignment> = g.pins.to_vec();
    let i = m.iter().position(|a| a.role == "bus voltage").unwrap();
    m[i].function = Function::Analog {
        peripheral: "ADC1",
        signal: "IN3",
    };
    assert_eq!(check(&m, &METADATA).len(), 1);
    // PC0 is on the 64-pin package only; PA16 is no pin.
    let mut m: Vec<Assignment> = g.pins.to_vec();
    m[0].pin = pin(Port::C, 0);
    m[1].pin = pin(Port::A, 16);
    let e = check(&m, &METADATA);
    assert_eq!(e.len(), 2, "{e:?}");
    // The same pin twice.
    let mut m: Vec<Assignment> = g.pins.to_vec();
    m[1].pin = m[0].pin;
    let e = check(&m, &METADATA);
    assert!(
        e.iter()
            .any(|l| l.contains("already used for encoder chip select")),
        "{e:?}"
    );
}
