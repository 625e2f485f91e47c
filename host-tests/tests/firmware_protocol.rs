//! The firmware's wire formats (firmware/src/protocol.rs, compiled here as is): the
//! serial frames a XiL host or a recorder speaks, and the trace hash.

#[path = "../../firmware/src/protocol.rs"]
#[allow(dead_code)] // the trace and cost formats are read by other tests
mod protocol;

use protocol::{Decoder, Fnv1a64, Frame};

#[test]
fn checksums_and_hash_match_their_reference_values() {
    // Fletcher-16 and FNV-1a 64 reference vectors.
    assert_eq!(protocol::fletcher16(b"abcde"), 0xC8F0);
    assert_eq!(protocol::fletcher16(b"abcdef"), 0x2057);
    assert_eq!(Fnv1a64::default().0, 0xcbf2_9ce4_8422_2325);
    let mut h = Fnv1a64::default();
    h.write(b"a");
    assert_eq!(h.0, 0xaf63_dc4c_8601_ec8c);
    let mut a = Fnv1a64::default();
    a.write_f32s(&[1.0, -0.0]);
    let mut b = Fnv1a64::default();
    b.write(&[0, 0, 0x80, 0x3f, 0, 0, 0, 0x80]);
    assert_eq!(a.0, b.0, "hash over the little-endian bits");
}

#[test]
fn fletcher16_with_deferred_reduction_equals_the_per_byte_definition() {
    // The firmware reduces the sums once per 5802 bytes; the definition, per byte.
    let reference = |bytes: &[u8]| {
        let (mut a, mut b) = (0u16, 0u16);
        for &x in bytes {
            a = (a + u16::from(x)) % 255;
            b = (b + a) % 255;
        }
        (b << 8) | a
    };
    let mut x = 0x1234_5678u32;
    let data: Vec<u8> = (0..20_000)
        .map(|_| {
            x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (x >> 24) as u8
        })
        .collect();
    // All 0xff is the worst case for the u32 sums across a whole 5802-byte chunk.
    let ones = vec![0xffu8; 12_000];
    for len in [0, 1, 2, 254, 255, 256, 261, 5801, 5802, 5803, 11_604, 12_000] {
        assert_eq!(protocol::fletcher16(&ones[..len]), reference(&ones[..len]), "0xff x {len}");
    }
    for len in (0..data.len()).step_by(997).chain([5802, 5803, 20_000]) {
        assert_eq!(protocol::fletcher16(&data[..len]), reference(&data[..len]), "{len} bytes");
    }
}

fn feed(d: &mut Decoder, bytes: &[u8]) -> Vec<Frame> {
    bytes.iter().filter_map(|b| d.push(*b)).collect()
}

#[test]
fn decoder_takes_set_points_exactly_and_resynchronises() {
    let sp = [37.5f32, -12.25, f32::from_bits(0x3dcc_cccd), 24.0];
    let frame = protocol::encode_inputs(sp[0], sp[1], sp[2], sp[3]);
    let mut end = [0u8; protocol::FRAME_OVERHEAD];
    let n = protocol::encode_frame(protocol::KIND_END, &[], &mut end).unwrap();

    let mut stream = vec![0xA5, 0x00, 0xA5, 0xA5]; // noise, including sync bytes
    stream.extend_from_slice(&frame);
    stream.extend_from_slice(&frame[..7]); // a frame cut short swallows...
    stream.extend_from_slice(&frame); // ...the start of the next one
    let mut bad = frame;
    bad[8] ^= 0x01; // one flipped payload bit
    stream.extend_from_slice(&bad);
    stream.extend_from_slice(&[0xA5, 0x5A, b'I', 3]); // wrong length for its kind
    stream.extend_from_slice(&frame);
    stream.extend_from_slice(&end[..n]);

    let mut d = Decoder::default();
    let got = feed(&mut d, &stream);
    assert_eq!(got.len(), 3, "{got:?}");
    for f in &got[..2] {
        let Frame::Inputs(v) = f else { panic!("{f:?}") };
        let bits = |a: &[f32; 4]| a.map(f32::to_bits);
        assert_eq!(bits(v), bits(&sp));
    }
    assert_eq!(got[2], Frame::End);
    // The cut frame and the one it swallowed, the flipped bit and the bad length were
    // refused: every loss is counted, none is silent.
    assert_eq!(d.rejected, 3);
}

#[test]
fn output_frames_are_found_in_a_noisy_capture() {
    let mut capture = b"\x00\x01defmt\xa5".to_vec();
    let mut buf = [0u8; 300];
    let vals = [1.5f32, -2.0, 1e-20];
    let n = protocol::encode_outputs(7, 123_000, &vals, &mut buf).unwrap();
    capture.extend_from_slice(&buf[..n]);
    let mut corrupt = buf[..n].to_vec();
    corrupt[10] ^= 0xff;
    capture.extend_from_slice(&corrupt);
    capture.extend_from_slice(&buf[..n]);
    capture.extend_from_slice(&buf[..n - 3]); // truncated at the end
    let frames: Vec<_> = protocol::frames(&capture).collect();
    assert_eq!(frames.len(), 2);
    for (kind, p) in frames {
        assert_eq!(kind, protocol::KIND_OUTPUTS);
        assert_eq!(u32::from_le_bytes(p[..4].try_into().unwrap()), 7);
        assert_eq!(u64::from_le_bytes(p[4..12].try_into().unwrap()), 123_000);
        let got: Vec<f32> =
            p[12..].chunks_exact(4).map(|b| f32::from_le_bytes(b.try_into().unwrap())).collect();
        assert_eq!(got, vals);
    }
    // A frame that does not fit is refused, not truncated.
    assert!(protocol::encode_outputs(0, 0, &[0.0; 62], &mut [0u8; 512]).is_none());
    assert!(protocol::encode_outputs(0, 0, &vals, &mut [0u8; 20]).is_none());
}
