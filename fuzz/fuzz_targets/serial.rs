//! The firmware's serial protocol (firmware/src/protocol.rs, compiled here from the
//! very file, as host-tests/src/rt.rs does): the byte-at-a-time `Decoder` the firmware
//! runs on its UART, and the host's capture scanner `frames`.
//!
//! The first byte picks a mode, the rest is the stream:
//! - even: raw bytes. Every frame `Decoder::push` yields must be the last bytes pushed,
//!   exactly as `encode_inputs`/`encode_frame` write it (so sync, kind, length and
//!   Fletcher-16 are valid and the decoded values are the payload's bits); every frame
//!   `frames` yields must be the bytes it came from, re-encoded, and frames must not
//!   overlap.
//! - odd: a description of a frame sequence (see `build`), encoded back to back. `frames`
//!   must give back exactly the sequence; when every frame is one the firmware accepts
//!   (`I` with 16 bytes, `E` with none), the `Decoder` must too.
#![no_main]

use libfuzzer_sys::fuzz_target;

#[path = "../../firmware/src/protocol.rs"]
#[allow(dead_code)]
mod protocol;

use protocol::{
    encode_frame, encode_inputs, fletcher16, frames, Decoder, Frame, FRAME_OVERHEAD, INPUTS_LEN, KIND_END,
    KIND_INPUTS, MAX_PAYLOAD, SYNC,
};

/// The wire bytes of a decoded frame.
fn encode(f: &Frame) -> Vec<u8> {
    match f {
        Frame::Inputs([a, b, c, d]) => encode_inputs(*a, *b, *c, *d).to_vec(),
        Frame::End => {
            let mut buf = [0u8; FRAME_OVERHEAD];
            let n = encode_frame(KIND_END, &[], &mut buf).expect("an empty frame fits");
            buf[..n].to_vec()
        }
    }
}

/// Check a frame's bytes against the format in the module doc.
fn check_wire(bytes: &[u8], kind: u8, payload: &[u8]) {
    let n = payload.len();
    assert_eq!(bytes.len(), n + FRAME_OVERHEAD);
    assert_eq!(bytes[..2], SYNC);
    assert_eq!((bytes[2], usize::from(bytes[3])), (kind, n));
    assert_eq!(&bytes[4..4 + n], payload);
    assert_eq!(u16::from_le_bytes([bytes[4 + n], bytes[5 + n]]), fletcher16(&bytes[2..4 + n]));
}

/// Feed `stream` byte by byte; the frames with the index of their last byte.
fn decode(stream: &[u8]) -> Vec<(usize, Frame)> {
    let mut d = Decoder::default();
    let mut out = Vec::new();
    for (i, &b) in stream.iter().enumerate() {
        if let Some(f) = d.push(b) {
            out.push((i, f));
        }
    }
    assert!(d.rejected as usize <= stream.len());
    out
}

/// `frames(stream)` with the offset of each frame's first byte.
fn scan(stream: &[u8]) -> Vec<(usize, u8, &[u8])> {
    frames(stream)
        .map(|(kind, payload)| {
            // The payload borrows from the stream: its offset locates the frame.
            let at = payload.as_ptr() as usize - stream.as_ptr() as usize;
            assert!(at >= 4 && at + payload.len() + 2 <= stream.len());
            (at - 4, kind, payload)
        })
        .collect()
}

fn check_raw(stream: &[u8]) {
    for (end, f) in decode(stream) {
        let wire = encode(&f);
        let start = (end + 1).checked_sub(wire.len()).expect("a frame longer than the bytes pushed");
        assert_eq!(&stream[start..=end], &wire[..], "decoded {f:?} is not the bytes it came from");
        let (kind, n) = match f {
            Frame::Inputs(_) => (KIND_INPUTS, INPUTS_LEN),
            Frame::End => (KIND_END, 0),
        };
        check_wire(&stream[start..=end], kind, &wire[4..4 + n]);
    }
    let mut next = 0;
    for (at, kind, payload) in scan(stream) {
        assert!(at >= next, "frames overlap");
        let frame = &stream[at..at + payload.len() + FRAME_OVERHEAD];
        check_wire(frame, kind, payload);
        let mut buf = [0u8; MAX_PAYLOAD + FRAME_OVERHEAD];
        let n = encode_frame(kind, payload, &mut buf).expect("a scanned payload fits a frame");
        assert_eq!(&buf[..n], frame, "re-encoding a scanned frame differs");
        next = at + n;
    }
}

/// A frame sequence from fuzz bytes: per frame a control byte (bit 0: accepted kinds
/// only, `I`/`E`; else a kind byte and a length byte follow) and the payload bytes
/// (zero-padded at the end of the input).
fn build(mut d: &[u8]) -> Vec<(u8, Vec<u8>)> {
    fn take(d: &mut &[u8], n: usize) -> Vec<u8> {
        let k = n.min(d.len());
        let mut v = d[..k].to_vec();
        v.resize(n, 0);
        *d = &d[k..];
        v
    }
    let mut out = Vec::new();
    while out.len() < 64 {
        let c = take(&mut d, 1)[0];
        let (kind, len) = if c & 1 == 0 {
            if c & 2 == 0 {
                (KIND_INPUTS, INPUTS_LEN)
            } else {
                (KIND_END, 0)
            }
        } else {
            let h = take(&mut d, 2);
            (h[0], usize::from(h[1]))
        };
        out.push((kind, take(&mut d, len)));
        if d.is_empty() {
            break;
        }
    }
    out
}

fn check_sequence(spec: &[u8]) {
    let seq = build(spec);
    let mut stream = Vec::new();
    let mut buf = [0u8; MAX_PAYLOAD + FRAME_OVERHEAD];
    for (kind, payload) in &seq {
        let n = encode_frame(*kind, payload, &mut buf).expect("payload <= 255 bytes fits");
        stream.extend_from_slice(&buf[..n]);
    }
    let scanned: Vec<(u8, Vec<u8>)> = scan(&stream).into_iter().map(|(_, k, p)| (k, p.to_vec())).collect();
    assert_eq!(scanned, seq, "frames() does not give back back-to-back frames");
    let accepted =
        |(k, p): &(u8, Vec<u8>)| matches!((*k, p.len()), (KIND_INPUTS, INPUTS_LEN) | (KIND_END, 0));
    if seq.iter().all(accepted) {
        let decoded: Vec<Vec<u8>> = decode(&stream).iter().map(|(_, f)| encode(f)).collect();
        let sent: Vec<Vec<u8>> = seq
            .iter()
            .map(|(k, p)| {
                let n = encode_frame(*k, p, &mut buf).expect("fits");
                buf[..n].to_vec()
            })
            .collect();
        assert_eq!(decoded, sent, "the decoder does not give back back-to-back frames");
    }
    check_raw(&stream);
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else { return };
    if mode & 1 == 0 {
        check_raw(rest);
    } else {
        check_sequence(rest);
    }
});
