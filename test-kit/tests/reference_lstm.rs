//! The reference f32 LSTM (`firmware::nn::reference`) on the golden network: the
//! fixed-size step and the shape-erased view compute the same bits, a reset equals a
//! fresh start, and wrong lengths are refused without a panic.
use firmware::nn::reference::LstmState;
use test_kit::golden;

#[test]
fn view_and_fixed_step_agree_bit_for_bit() {
    let net = golden::lstm_network();
    let view = net.view();
    view.check().unwrap();
    let mut fixed = LstmState::new();
    let (mut h, mut c) = ([0.0f32; golden::LSTM_H], [0.0f32; golden::LSTM_H]);
    let (mut e, mut hn) = ([0.0f32; golden::LSTM_E], [0.0f32; golden::LSTM_H]);
    for t in 0..500 {
        let x = golden::lstm_input(t);
        let y = net.step(&mut fixed, &x);
        let mut y2 = [0.0f32; golden::LSTM_O];
        view.step(&mut h, &mut c, &mut e, &mut hn, &x, &mut y2)
            .unwrap();
        assert_eq!(y.map(f32::to_bits), y2.map(f32::to_bits), "step {t}");
    }
}

#[test]
fn reset_mid_sequence_equals_a_fresh_start() {
    let net = golden::lstm_network();
    let mut run = LstmState::new();
    for t in 0..300 {
        net.step(&mut run, &golden::lstm_input(t));
    }
    assert_ne!(run, LstmState::new());
    run.reset();
    let mut fresh = LstmState::new();
    for t in 300..600 {
        let x = golden::lstm_input(t);
        assert_eq!(net.step(&mut run, &x), net.step(&mut fresh, &x), "step {t}");
    }
}

#[test]
fn wrong_lengths_are_rejected_without_panic() {
    let net = golden::lstm_network();
    let mut view = net.view();
    view.w_hh = &view.w_hh[1..];
    assert_eq!(view.check().unwrap_err().field, "lstm.weight_hh_l0");
    let view = net.view();
    let (mut h, mut c) = ([0.0f32; golden::LSTM_H], [0.0f32; golden::LSTM_H]);
    let (mut e, mut hn) = ([0.0f32; golden::LSTM_E], [0.0f32; golden::LSTM_H]);
    let mut y = [0.0f32; golden::LSTM_O + 1];
    let err = view
        .step(
            &mut h,
            &mut c,
            &mut e,
            &mut hn,
            &[0.0; golden::LSTM_I],
            &mut y,
        )
        .unwrap_err();
    assert_eq!(err.field, "out");
}
