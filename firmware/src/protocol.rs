//! Wire formats shared by the firmware and the host: the serial frames (set points in,
//! outputs out) and the trace stream of the bit-for-bit proof.
//!
//! Pure `core` code with no crate paths, so the host tests compile this very file
//! (`#[path]`) instead of re-implementing the formats.
//!
//! Serial frame, little-endian:
//!
//! ```text
//! 0xA5 0x5A | kind: u8 | len: u8 | payload: len bytes | fletcher16(kind..payload): u16
//! ```
//!
//! - `b'I'` set points, 16 bytes: throttle %, load L %, load R %, supply V (`f32`).
//! - `b'E'` end of stream, no payload: the XiL run stops.
//! - `b'O'` outputs: `seq: u32`, `t_us: u64`, then the channel values (`f32`).
//! - `b'S'` loop statistics at the end of a run: [`STATS_FIELDS`] `u32`s.

/// First two bytes of every serial frame.
pub const SYNC: [u8; 2] = [0xA5, 0x5A];
/// Set-point frame kind.
pub const KIND_INPUTS: u8 = b'I';
/// End-of-stream frame kind.
pub const KIND_END: u8 = b'E';
/// Output frame kind.
pub const KIND_OUTPUTS: u8 = b'O';
/// Statistics frame kind.
pub const KIND_STATS: u8 = b'S';
/// The `u32` fields of a statistics frame, in order.
pub const STATS_FIELDS: [&str; 12] = [
    "steps",
    "late",
    "overruns",
    "missed_ticks",
    "mean_step_cycles",
    "max_step_cycles",
    "max_latency_cycles",
    "period_cycles",
    "frames_dropped",
    "inputs_received",
    "inputs_rejected",
    "stack_bytes",
];
/// Payload bytes of a set-point frame.
pub const INPUTS_LEN: usize = 16;
/// Largest payload a frame may carry (a `u8` length).
pub const MAX_PAYLOAD: usize = 255;
/// Bytes around a payload: sync, kind, length, checksum.
pub const FRAME_OVERHEAD: usize = 6;

/// Fletcher-16: cheap, and unlike a plain sum it catches swapped bytes.
pub fn fletcher16(bytes: &[u8]) -> u16 {
    // Sums reduced mod 255 once per 5802 bytes instead of every byte (the same
    // result): up to 5802 bytes keep both within u32. A frame is at most 261 bytes, so
    // the output frame costs two divisions, not 2 per byte, inside the step's budget.
    let (mut a, mut b) = (0u32, 0u32);
    for chunk in bytes.chunks(5802) {
        for &x in chunk {
            a += u32::from(x);
            b += a;
        }
        a %= 255;
        b %= 255;
    }
    ((b as u16) << 8) | a as u16
}

/// Write a frame of `kind` around `payload` into `buf`; the frame length, or `None`
/// when `buf` is too small or the payload too long.
pub fn encode_frame(kind: u8, payload: &[u8], buf: &mut [u8]) -> Option<usize> {
    let n = payload.len();
    if n > MAX_PAYLOAD {
        return None;
    }
    let frame = buf.get_mut(..n + FRAME_OVERHEAD)?;
    frame[..4].copy_from_slice(&[SYNC[0], SYNC[1], kind, n as u8]);
    frame[4..4 + n].copy_from_slice(payload);
    let ck = fletcher16(&frame[2..4 + n]);
    frame[4 + n..].copy_from_slice(&ck.to_le_bytes());
    Some(n + FRAME_OVERHEAD)
}

/// Encode an output frame: `seq`, `t_us` and `values`; the frame length, or `None` when
/// it does not fit `buf` or a frame.
pub fn encode_outputs(seq: u32, t_us: u64, values: &[f32], buf: &mut [u8]) -> Option<usize> {
    encode_outputs_with(seq, t_us, values.iter().copied(), values.len(), buf)
}

/// [`encode_outputs`] of `n` values taken from an iterator, written straight into `buf`
/// (no intermediate copies: this runs inside the step's time budget).
pub fn encode_outputs_with(
    seq: u32,
    t_us: u64,
    values: impl Iterator<Item = f32>,
    n: usize,
    buf: &mut [u8],
) -> Option<usize> {
    let len = 12 + 4 * n;
    if len > MAX_PAYLOAD {
        return None;
    }
    let frame = buf.get_mut(..len + FRAME_OVERHEAD)?;
    frame[..4].copy_from_slice(&[SYNC[0], SYNC[1], KIND_OUTPUTS, len as u8]);
    frame[4..8].copy_from_slice(&seq.to_le_bytes());
    frame[8..16].copy_from_slice(&t_us.to_le_bytes());
    let mut filled = 0;
    for (dst, v) in frame[16..4 + len].chunks_exact_mut(4).zip(values) {
        dst.copy_from_slice(&v.to_le_bytes());
        filled += 1;
    }
    if filled != n {
        return None;
    }
    let ck = fletcher16(&frame[2..4 + len]);
    frame[4 + len..].copy_from_slice(&ck.to_le_bytes());
    Some(len + FRAME_OVERHEAD)
}

/// Encode a set-point frame.
pub fn encode_inputs(throttle: f32, load_l: f32, load_r: f32, supply_v: f32) -> [u8; 22] {
    let mut payload = [0u8; INPUTS_LEN];
    for (dst, v) in payload.chunks_exact_mut(4).zip([throttle, load_l, load_r, supply_v]) {
        dst.copy_from_slice(&v.to_le_bytes());
    }
    let mut out = [0u8; INPUTS_LEN + FRAME_OVERHEAD];
    // The buffer is sized for exactly this frame.
    let _ = encode_frame(KIND_INPUTS, &payload, &mut out);
    out
}

/// Iterate over the valid frames in a captured byte stream: `(kind, payload)`.
/// Bytes outside frames and frames with a bad checksum are skipped.
pub struct Frames<'a> {
    bytes: &'a [u8],
    pos: usize,
}

/// The valid frames in `bytes`.
pub fn frames(bytes: &[u8]) -> Frames<'_> {
    Frames { bytes, pos: 0 }
}

impl<'a> Iterator for Frames<'a> {
    type Item = (u8, &'a [u8]);

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            let rest = self.bytes.get(self.pos..)?;
            let start = rest.windows(2).position(|w| w == SYNC)?;
            let at = self.pos + start;
            let frame = self.bytes.get(at..)?;
            let (kind, n) = (*frame.get(2)?, usize::from(*frame.get(3)?));
            let Some(whole) = frame.get(..n + FRAME_OVERHEAD) else {
                return None; // truncated at the end of the capture
            };
            let ck = u16::from_le_bytes([whole[4 + n], whole[5 + n]]);
            if ck == fletcher16(&whole[2..4 + n]) {
                self.pos = at + n + FRAME_OVERHEAD;
                return Some((kind, &whole[4..4 + n]));
            }
            self.pos = at + 1;
        }
    }
}

/// A frame the firmware accepts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Frame {
    /// Throttle %, load L %, load R %, supply V.
    Inputs([f32; 4]),
    /// End of the XiL stream.
    End,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    Sync0,
    Sync1,
    Kind,
    Len,
    Payload,
    Check0,
    Check1,
}

/// Byte-at-a-time decoder for incoming frames: never blocks, never allocates, and
/// resynchronises on the next sync pattern after garbage or a bad checksum.
#[derive(Debug, Clone)]
pub struct Decoder {
    state: State,
    kind: u8,
    len: usize,
    pos: usize,
    buf: [u8; INPUTS_LEN],
    check_lo: u8,
    sum: (u16, u16),
    /// Frames dropped for a bad length, kind or checksum.
    pub rejected: u32,
}

impl Default for Decoder {
    fn default() -> Self {
        Self {
            state: State::Sync0,
            kind: 0,
            len: 0,
            pos: 0,
            buf: [0; INPUTS_LEN],
            check_lo: 0,
            sum: (0, 0),
            rejected: 0,
        }
    }
}

impl Decoder {
    fn absorb(&mut self, byte: u8) {
        let (a, b) = self.sum;
        let a = (a + u16::from(byte)) % 255;
        self.sum = (a, (b + a) % 255);
    }

    /// Feed one byte; a frame once one is complete and valid.
    pub fn push(&mut self, byte: u8) -> Option<Frame> {
        match self.state {
            State::Sync0 => {
                if byte == SYNC[0] {
                    self.state = State::Sync1;
                }
            }
            State::Sync1 => {
                self.state = if byte == SYNC[1] {
                    State::Kind
                } else if byte == SYNC[0] {
                    State::Sync1
                } else {
                    State::Sync0
                };
            }
            State::Kind => {
                self.kind = byte;
                self.sum = (0, 0);
                self.absorb(byte);
                self.state = State::Len;
            }
            State::Len => {
                self.len = usize::from(byte);
                self.pos = 0;
                self.absorb(byte);
                let ok = matches!((self.kind, self.len), (KIND_INPUTS, INPUTS_LEN) | (KIND_END, 0));
                self.state = if !ok {
                    self.rejected = self.rejected.wrapping_add(1);
                    State::Sync0
                } else if self.len == 0 {
                    State::Check0
                } else {
                    State::Payload
                };
            }
            State::Payload => {
                self.absorb(byte);
                if let Some(slot) = self.buf.get_mut(self.pos) {
                    *slot = byte;
                }
                self.pos += 1;
                if self.pos >= self.len {
                    self.state = State::Check0;
                }
            }
            State::Check0 => {
                self.check_lo = byte;
                self.state = State::Check1;
            }
            State::Check1 => {
                self.state = State::Sync0;
                let got = u16::from_le_bytes([self.check_lo, byte]);
                let (a, b) = self.sum;
                if got != (b << 8) | a {
                    self.rejected = self.rejected.wrapping_add(1);
                    return None;
                }
                return Some(if self.kind == KIND_END {
                    Frame::End
                } else {
                    let mut v = [0f32; 4];
                    for (dst, src) in v.iter_mut().zip(self.buf.chunks_exact(4)) {
                        *dst = f32::from_le_bytes([src[0], src[1], src[2], src[3]]);
                    }
                    Frame::Inputs(v)
                });
            }
        }
        None
    }
}

// ---------------------------------------------------------------------------------
// Trace stream (semihosting file, little-endian):
//
//   file:  TRACE_MAGIC | n_channels: u16 | dt_us: u32 | n_effects: u16
//          | n_effects x (id_len: u8, id, key_len: u8, key, value bits: u32)
//          | runs ... | DONE_MAGIC | n_runs: u32
//   run:   RUN_MAGIC | profile name: [u8; 8] (NUL padded) | rate set: u8 (0 programmed,
//          1 identified) | n_steps: u32
//          | n_steps x (t_us: u64, n_channels x value bits: u32)
//          | END_MAGIC | fnv1a64 over the channel bits of every step: u64
// ---------------------------------------------------------------------------------

/// Start of a trace file (format version 1).
pub const TRACE_MAGIC: [u8; 8] = *b"SRTRACE1";
/// Magic of a fixed-point build's trace: the same layout, each value the I17F15 bits of
/// `model_core::Fx` instead of an f32's (version 2: version 1 carried 8-byte I32F32).
pub const TRACE_MAGIC_FX: [u8; 8] = *b"SRTRACX2";
/// Start of a run.
pub const RUN_MAGIC: [u8; 4] = *b"RUN\0";
/// End of a run, before its hash.
pub const END_MAGIC: [u8; 4] = *b"END\0";
/// End of the file, before the run count.
pub const DONE_MAGIC: [u8; 4] = *b"DONE";
/// Name of the trace file the firmware writes in QEMU's working directory.
pub const TRACE_FILE: &str = "simrod-trace.bin";

/// FNV-1a, 64-bit: the trace hash (golden files, firmware-side check). Not
/// cryptographic; it only has to change when any bit of any value changes.
#[derive(Debug, Clone, Copy)]
pub struct Fnv1a64(pub u64);

impl Default for Fnv1a64 {
    fn default() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv1a64 {
    /// Absorb bytes.
    #[inline]
    pub fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    /// Absorb the little-endian bits of every value.
    #[inline]
    pub fn write_f32s(&mut self, values: &[f32]) {
        for v in values {
            self.write(&v.to_bits().to_le_bytes());
        }
    }
}

// ---------------------------------------------------------------------------------
// Cost stream of `simrod-cost` (semihosting file, little-endian, every field a u32
// unless noted):
//
//   file:  COST_MAGIC | ns_per_insn | timer_hz | n_blocks (0: no block profile)
//          | n_cal | n_cal x (nops, instructions, raw timer counts)
//          | mark_overhead (instructions between two back-to-back probe calls; 0
//          | without block profile) | stack_window (bytes painted below the step)
//          | runs ... | DONE_MAGIC | n_runs
//   run:   RUN_MAGIC | profile name: [u8; 8] (NUL padded) | rate set: u8 (0
//          programmed, 1 identified) | n_steps
//          | n_steps x (COST_FIXED_WORDS + 2 n_blocks words: profile_at instructions,
//            step instructions, step stack bytes, then per block its instructions
//            and the number of intervals they were summed over)
//          | END_MAGIC | fnv1a64 over the channel bits of every step: u64
//
// Instructions are counted by QEMU's `-icount shift=S` (one instruction = 2^S ns of
// virtual time) through the 25 MHz SysTick: with S >= 7 one instruction moves the
// timer by at least 3.2 counts, so every interval converts to an exact instruction
// count; the calibration records (nops) prove it.
// ---------------------------------------------------------------------------------

/// Start of a cost file (format version 1).
pub const COST_MAGIC: [u8; 8] = *b"SRCOST1\0";
/// Name of the cost file the firmware writes in QEMU's working directory.
pub const COST_FILE: &str = "simrod-cost.bin";
/// Words of a cost record before the per-block words.
pub const COST_FIXED_WORDS: usize = 3;
/// Names of the profiled blocks, in record order: the call into the step (argument
/// set-up, prologue), then model-core's `probe::Block`s.
pub const COST_BLOCKS: [&str; 7] =
    ["call", "rate logic", "tables", "controller", "mechanics", "electrics", "outputs"];
