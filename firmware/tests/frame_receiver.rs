//! The state-bus frame receiver against a specification written here: scanning the
//! byte stream from the left, a frame is taken at the first offset where 37 bytes
//! decode (sync marker and CRC), the scan resumes after its last byte, and an offset
//! whose 37 bytes do not decode is skipped by one byte. The receiver must yield
//! exactly those frames, each on the byte that completes it, on streams of valid
//! frames mixed with noise, stray sync bytes, cut and corrupted frames.

use firmware::control::message::FRAME_SYNC;
use firmware::control::{FrameReceiver, JointState, JointStateMessage};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const N: usize = JointStateMessage::WIRE_LEN;

/// The specification: (index of the completing byte, message) of every frame taken.
fn spec_frames(bytes: &[u8]) -> Vec<(usize, JointStateMessage)> {
    let mut out = Vec::new();
    let mut s = 0;
    while s + N <= bytes.len() {
        let window: &[u8; N] = bytes[s..s + N].try_into().unwrap();
        match JointStateMessage::decode(window) {
            Some(m) => {
                out.push((s + N - 1, m));
                s += N;
            }
            None => s += 1,
        }
    }
    out
}

/// What the receiver yields, byte by byte.
fn received(bytes: &[u8]) -> Vec<(usize, JointStateMessage)> {
    let mut rx = FrameReceiver::new();
    bytes
        .iter()
        .enumerate()
        .filter_map(|(k, &b)| rx.push(b).map(|m| (k, m)))
        .collect()
}

fn frame(sequence: u16, q_ref_rad: f32) -> [u8; N] {
    JointStateMessage {
        joint: 1,
        session: 7,
        sequence,
        timestamp_us: 1000 * u32::from(sequence),
        state: JointState::from_array([q_ref_rad, 0.5, -1.0, 0.25, 0.0, 3.0]),
    }
    .encode()
}

/// A reference position whose bytes hold the sync marker (a false start inside a field).
fn marker_in_field() -> f32 {
    f32::from_le_bytes([0x00, FRAME_SYNC[0], FRAME_SYNC[1], 0x3F])
}

#[test]
fn a_stray_first_sync_byte_before_a_frame_loses_nothing() {
    // A5 | A5 5A ...: the frame starts on the second byte.
    let mut bytes = vec![FRAME_SYNC[0]];
    bytes.extend_from_slice(&frame(1, 0.5));
    let got = received(&bytes);
    assert_eq!(got.len(), 1, "{got:?}");
    assert_eq!((got[0].0, got[0].1.sequence), (N, 1));
    // A5 x A5 5A ...: a wrong second byte, then the frame.
    let mut bytes = vec![FRAME_SYNC[0], 0x11];
    bytes.extend_from_slice(&frame(2, 0.5));
    assert_eq!(received(&bytes), spec_frames(&bytes));
    assert_eq!(received(&bytes).len(), 1);
}

#[test]
fn a_frame_starting_on_the_last_byte_of_a_bad_window_is_kept() {
    // A false start (A5 5A then 34 bytes without a marker): the window's last byte is
    // the first sync byte of a real frame.
    let mut bytes = vec![FRAME_SYNC[0], FRAME_SYNC[1]];
    bytes.extend((0..N as u8 - 3).map(|k| k.wrapping_mul(3)));
    assert!(!bytes.windows(2).skip(1).any(|w| w == FRAME_SYNC));
    bytes.extend_from_slice(&frame(3, 0.5));
    assert!(JointStateMessage::decode(bytes[..N].try_into().unwrap()).is_none());
    let got = received(&bytes);
    assert_eq!(got.len(), 1, "{got:?}");
    assert_eq!((got[0].0, got[0].1.sequence), (2 * N - 2, 3));
    assert_eq!(got, spec_frames(&bytes));
}

#[test]
fn the_receiver_takes_exactly_the_specified_frames_of_hostile_streams() {
    let mut rng = ChaCha8Rng::seed_from_u64(0x5eed_f4a3);
    let mut total = 0;
    for stream in 0..3000 {
        let mut bytes = Vec::new();
        let mut seq = 0u16;
        while bytes.len() < 400 {
            seq = seq.wrapping_add(1);
            let q = if rng.gen_bool(0.3) {
                marker_in_field()
            } else {
                rng.gen_range(-3.0..3.0)
            };
            let f = frame(seq, q);
            match rng.gen_range(0..10) {
                0 => bytes.push(FRAME_SYNC[0]),
                1 => bytes.extend_from_slice(&FRAME_SYNC),
                2 => {
                    let cut = rng.gen_range(1..N);
                    bytes.extend_from_slice(&f[..cut]);
                }
                3 => {
                    let mut bad = f;
                    bad[rng.gen_range(2..N)] ^= 1 << rng.gen_range(0..8);
                    bytes.extend_from_slice(&bad);
                }
                4 => {
                    // Noise dense in sync bytes.
                    for _ in 0..rng.gen_range(1..40) {
                        bytes.push(match rng.gen_range(0..4) {
                            0 => FRAME_SYNC[0],
                            1 => FRAME_SYNC[1],
                            _ => rng.r#gen(),
                        });
                    }
                }
                _ => bytes.extend_from_slice(&f),
            }
        }
        let want = spec_frames(&bytes);
        total += want.len();
        assert_eq!(received(&bytes), want, "stream {stream}: {bytes:02x?}");
    }
    // The streams do carry frames (the comparison is not between two empty lists).
    assert!(total > 3000 * 4, "{total} frames");
}
