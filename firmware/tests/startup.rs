//! One board image, three joints: the start-up path the board runs
//! (`control::plan_startup` on its configuration block and the compiled-in model's
//! joints and profiles), on the host. The same compiled-in model configured as robot
//! joint 4, 5 or 6 drives and compensates that joint; a refused block runs no
//! compensator.
use firmware::control::{
    Compensator, JointConfigBlock, JointConfigFault, LstmPredictor, SubsetModel, plan_startup,
};
use firmware::model::default as compiled;

const PWM_HZ: f32 = 20_000.0;

fn block(joint_number: u8) -> [u8; JointConfigBlock::LEN] {
    JointConfigBlock {
        joint_number,
        bus_key: *b"startup-test-key",
    }
    .encode()
}

#[test]
fn one_image_runs_as_joint_4_5_or_6_by_its_configuration_block() {
    const J: usize = compiled::JOINT_INDICES.len();
    // Each of the compiled-in model's joints (1-based number, its slot in the model).
    for (slot, &index) in compiled::JOINT_INDICES.iter().enumerate() {
        let number = u8::try_from(index + 1).expect("a joint number fits a byte");
        let plan = plan_startup(
            &block(number),
            &compiled::JOINT_INDICES,
            &compiled::JOINT_PROFILES,
            PWM_HZ,
            compiled::CONTROL_RATE_HZ,
        );
        let joint = plan.joint.expect("configured");
        assert_eq!((joint.joint_number, joint.slot), (number, slot));
        let profile = compiled::JOINT_PROFILES[slot];
        assert_eq!(plan.drive, Some(profile.drive_config(PWM_HZ)));
        let config = plan.compensator.expect("compensator");
        assert_eq!(config.own_joint, slot);
        assert_eq!(config.rate_hz, compiled::CONTROL_RATE_HZ as f32);
        // The compensator the board builds from it accepts the configuration.
        let model = SubsetModel {
            model: &compiled::DYNAMICS,
            joints: firmware::model::dynamics_indices(
                compiled::JOINT_INDICES,
                compiled::DYNAMICS_JOINTS,
            ),
            fixed_q_rad: [0.0; compiled::DYNAMICS_JOINTS],
        };
        let lstm = LstmPredictor::<_, J, { compiled::INPUTS }>::new(
            &compiled::NETWORK,
            compiled::FEATURE_PRESET,
        )
        .expect("lstm");
        assert!(Compensator::<J, _, _>::new(config, model, lstm).is_ok());
    }
}

#[test]
fn a_refused_block_runs_without_feedforward() {
    // A joint number the compiled-in model does not compensate, and one it does.
    let absent = (1u8..=u8::MAX)
        .find(|&n| !compiled::JOINT_INDICES.contains(&(usize::from(n) - 1)))
        .expect("some joint number is not compiled in");
    let present = u8::try_from(compiled::JOINT_INDICES[0] + 1).expect("fits a byte");
    for (bytes, fault) in [
        ([0xFF; JointConfigBlock::LEN], JointConfigFault::Erased),
        (block(absent), JointConfigFault::JointNotCompensated(absent)),
        (
            {
                let mut b = block(present);
                b[5] = present.wrapping_add(1); // another joint with this joint's CRC
                b
            },
            JointConfigFault::BadCrc,
        ),
    ] {
        let plan = plan_startup(
            &bytes,
            &compiled::JOINT_INDICES,
            &compiled::JOINT_PROFILES,
            PWM_HZ,
            compiled::CONTROL_RATE_HZ,
        );
        assert_eq!(plan.joint, Err(fault));
        assert_eq!(plan.compensator, None);
    }
}
