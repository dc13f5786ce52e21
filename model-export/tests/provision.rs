//! `model-export provision` round trip: the block the host writes is the one the
//! firmware's start-up accepts for the right joint (with the robot's key) and refuses
//! when altered or when the image does not compensate that joint; bad key files are
//! named and leave the output as it was.
use firmware::control::{JointConfigBlock, JointConfigFault, JointSlot, select_joint};
use firmware::model::default::{JOINT_INDICES, JOINT_PROFILES};
use model_export::cli::run_args as cli;
use model_export::cmd::provision::probe_rs_line;

const KEY_HEX: &str = "00112233445566778899aabbccddeeff";

fn provision(dir: &std::path::Path, joint: u8, key_text: &str) -> anyhow::Result<Vec<u8>> {
    let key = dir.join("robot.key");
    std::fs::write(&key, key_text).unwrap();
    let out = dir.join(format!("joint{joint}.bin"));
    cli(&[
        "provision",
        "--joint",
        &joint.to_string(),
        "--key-file",
        &key.display().to_string(),
        "--out",
        &out.display().to_string(),
    ])?;
    Ok(std::fs::read(out).unwrap())
}

#[test]
fn the_provisioned_block_is_accepted_for_its_joint_and_refused_when_altered() {
    let dir = tempfile::tempdir().unwrap();
    let key: [u8; 16] = core::array::from_fn(|k| 0x11 * k as u8);
    // Each joint the compiled-in model compensates (1-based number, its slot).
    for (slot, &index) in JOINT_INDICES.iter().enumerate() {
        let joint = u8::try_from(index + 1).unwrap();
        let bytes = provision(dir.path(), joint, &format!("{KEY_HEX}\n")).unwrap();
        let block: [u8; JointConfigBlock::LEN] = bytes.as_slice().try_into().unwrap();
        assert_eq!(
            select_joint(&block, &JOINT_INDICES, &JOINT_PROFILES),
            Ok(JointSlot {
                slot,
                joint_number: joint,
                bus_key: key
            })
        );
        // Every single-bit and every byte alteration is refused.
        for byte in 0..block.len() {
            for flip in (0..8).map(|b| 1u8 << b).chain([0xFF, 0x5A]) {
                let mut b = block;
                b[byte] ^= flip;
                let r = select_joint(&b, &JOINT_INDICES, &JOINT_PROFILES);
                assert!(r.is_err(), "byte {byte} ^ {flip:#x}: {r:?}");
            }
        }
    }
    // A joint the image does not compensate: refused by the start-up.
    let absent = (1u8..=u8::MAX)
        .find(|&n| !JOINT_INDICES.contains(&(usize::from(n) - 1)))
        .unwrap();
    let bytes = provision(dir.path(), absent, KEY_HEX).unwrap();
    let block: [u8; JointConfigBlock::LEN] = bytes.as_slice().try_into().unwrap();
    assert_eq!(
        select_joint(&block, &JOINT_INDICES, &JOINT_PROFILES),
        Err(JointConfigFault::JointNotCompensated(absent))
    );
    assert_eq!(
        probe_rs_line(std::path::Path::new("joint5.bin")),
        "probe-rs download --chip STM32G474RETx --binary-format bin --base-address 0x0807F800 joint5.bin"
    );
    // The page address is board/memory.x's.
    let memory_x = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../board/memory.x"),
    )
    .unwrap();
    assert!(memory_x.contains("BOARD_CONFIG : ORIGIN = 0x0807F800"));
}

#[test]
fn bad_key_files_are_named_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("joint5.bin");
    std::fs::write(&out, b"old").unwrap();
    for (text, want) in [
        ("0011", "4 hex digits, 32 wanted"),
        ("00112233445566778899aabbccddeeff00", "34 hex digits"),
        (
            "0011223344556677\n8899aabbccddeefg",
            "robot.key:2:16: the bus key: `g`",
        ),
        ("00000000000000000000000000000000", "all zero"),
        ("ffffffffffffffffffffffffffffffff", "all 0xFF"),
    ] {
        let err = provision(dir.path(), 5, text).unwrap_err();
        let msg = format!("{err:#}");
        assert!(msg.contains(want) && msg.contains("robot.key"), "{msg}");
        assert_eq!(std::fs::read(&out).unwrap(), b"old");
    }
    let err = provision(dir.path(), 0, KEY_HEX).unwrap_err();
    assert!(format!("{err:#}").contains("--joint"), "{err:#}");
    assert_eq!(std::fs::read(&out).unwrap(), b"old");
}

/// board/README.md's provisioning block, run as written in a temporary directory (`$ME`
/// the model-export binary); the probe-rs line it prints is the README's next line
/// (which needs a probe: xtask's `board_commands_run_on_a_probe`).
#[test]
fn readme_provisioning_commands_run() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let text = std::fs::read_to_string(root.join("board/README.md")).unwrap();
    let start = text.find("**Provisioning.**").expect("the README section");
    let block = &text[start..];
    let open = block.find("```sh\n").expect("a sh block") + 6;
    let close = open + block[open..].find("```").expect("the block's end");
    let lines: Vec<&str> = block[open..close].lines().collect();
    let [_, od, me, probe] = lines[..] else {
        panic!("{lines:?}")
    };
    let dir = tempfile::tempdir().unwrap();
    let o = std::process::Command::new("sh")
        .args(["-c", od])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(o.status.success(), "{od}: {o:?}");
    let args: Vec<&str> = me
        .strip_prefix("$ME ")
        .unwrap()
        .split_whitespace()
        .collect();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_model-export"))
        .args(&args)
        .current_dir(dir.path())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{me}: {o:?}");
    assert!(stdout.lines().any(|l| l == probe), "{stdout}");
    let block: [u8; JointConfigBlock::LEN] = std::fs::read(dir.path().join("joint5.bin"))
        .unwrap()
        .try_into()
        .unwrap();
    // Joint 5 (index 4) in the compiled-in model's slot order, refused if not compiled in.
    let selected = select_joint(&block, &JOINT_INDICES, &JOINT_PROFILES);
    match JOINT_INDICES.iter().position(|&i| i == 4) {
        Some(slot) => {
            let s = selected.unwrap();
            assert_eq!((s.slot, s.joint_number), (slot, 5));
        }
        None => assert_eq!(selected, Err(JointConfigFault::JointNotCompensated(5))),
    }
}
