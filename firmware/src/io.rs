//! Where set points come from and where outputs go, as small traits over
//! `embedded-io`, so the loop is the same for the built-in profile, a XiL serial
//! stream, or whatever a port adds (CAN, analog inputs...).

use embedded_io::{Read, ReadReady, Write, WriteReady};
use model_core::{Channel, Inputs, Outputs, Profile, Real, SetPoints};

use crate::protocol::{self, Decoder, Frame};
use crate::step::simrod_profile_at;

/// A source of each step's inputs.
pub trait SetPointSource {
    /// Inputs for the step starting at model time `t_us`; `None` ends the run.
    /// Must not block: it is called inside the step's time budget.
    fn next_inputs(&mut self, t_us: u64) -> Option<Inputs>;
}

/// The built-in profile from flash (the PLC's basic mode).
pub struct ProfileSource {
    profile: Profile,
    supply_v: f32,
}

impl ProfileSource {
    /// A profile at a fixed supply voltage.
    pub fn new(profile: Profile, supply_v: f32) -> Self {
        Self { profile, supply_v }
    }
}

impl SetPointSource for ProfileSource {
    fn next_inputs(&mut self, t_us: u64) -> Option<Inputs> {
        (t_us < self.profile.duration_us())
            .then(|| Inputs { sp: simrod_profile_at(&self.profile, t_us), supply_v: self.supply_v })
    }
}

/// Set points streamed over a serial link (XiL): frames as in [`protocol`], decoded
/// from whatever bytes have arrived; the last valid set points hold between frames
/// (zero-order hold, like the PLC's analog outputs).
pub struct SerialSource<R> {
    rx: R,
    decoder: Decoder,
    last: Inputs,
    ended: bool,
    /// Valid set-point frames received.
    pub frames: u32,
}

/// Bytes taken from the link per step at most, so a flood cannot eat the budget.
const MAX_RX_PER_STEP: usize = 64;

impl<R: Read + ReadReady> SerialSource<R> {
    /// Start with all set points at zero and the given supply voltage.
    pub fn new(rx: R, supply_v: f32) -> Self {
        Self {
            rx,
            decoder: Decoder::default(),
            last: Inputs { sp: SetPoints::default(), supply_v },
            ended: false,
            frames: 0,
        }
    }

    /// Frames rejected for bad length, kind or checksum.
    pub fn rejected(&self) -> u32 {
        self.decoder.rejected
    }
}

impl<R: Read + ReadReady> SetPointSource for SerialSource<R> {
    fn next_inputs(&mut self, _t_us: u64) -> Option<Inputs> {
        let mut budget = MAX_RX_PER_STEP;
        while !self.ended && budget > 0 && matches!(self.rx.read_ready(), Ok(true)) {
            budget -= 1;
            let mut b = [0u8; 1];
            if !matches!(self.rx.read(&mut b), Ok(1)) {
                break;
            }
            match self.decoder.push(b[0]) {
                Some(Frame::Inputs([thr, ll, lr, v])) => {
                    self.last =
                        Inputs { sp: SetPoints { throttle_pct: thr, load_pct: [ll, lr] }, supply_v: v };
                    self.frames = self.frames.wrapping_add(1);
                }
                Some(Frame::End) => self.ended = true,
                None => {}
            }
        }
        (!self.ended).then_some(self.last)
    }
}

/// A consumer of the step outputs.
pub trait OutputSink {
    /// Queue one step's outputs; must not block.
    fn push(&mut self, out: &Outputs<crate::Scalar>);
    /// Move queued bytes towards the link while the loop is idle; true while
    /// something is still queued.
    fn poll(&mut self) -> bool;
}

/// Outputs as serial frames of the chosen channels. One frame is queued at a time and
/// sent from the idle time between steps; a frame that arrives while the previous is
/// still going out is dropped and counted, so a slow link never stalls the loop.
pub struct SerialSink<W> {
    tx: W,
    channels: &'static [Channel],
    buf: [u8; protocol::MAX_PAYLOAD + protocol::FRAME_OVERHEAD],
    len: usize,
    pos: usize,
    seq: u32,
    /// Frames dropped because the link was busy.
    pub dropped: u32,
}

impl<W: Write + WriteReady> SerialSink<W> {
    /// Stream `channels` (at most 60, to fit a frame).
    pub fn new(tx: W, channels: &'static [Channel]) -> Self {
        Self {
            tx,
            channels,
            buf: [0; protocol::MAX_PAYLOAD + protocol::FRAME_OVERHEAD],
            len: 0,
            pos: 0,
            seq: 0,
            dropped: 0,
        }
    }
}

impl<W: Write + WriteReady> SerialSink<W> {
    /// Send a frame now, blocking until it is out (after the loop, e.g. the
    /// statistics); whatever is queued goes first. False if it cannot be encoded.
    pub fn send_now(&mut self, kind: u8, payload: &[u8]) -> bool {
        while self.poll() {}
        let Some(len) = protocol::encode_frame(kind, payload, &mut self.buf) else {
            return false;
        };
        self.len = len;
        self.pos = 0;
        while self.poll() {}
        let _ = self.tx.flush();
        true
    }
}

impl<W: Write + WriteReady> OutputSink for SerialSink<W> {
    fn push(&mut self, out: &Outputs<crate::Scalar>) {
        if self.pos < self.len {
            self.dropped = self.dropped.wrapping_add(1);
            return;
        }
        // The stream carries f32 (the fixed-point twin's values rounded to f32).
        let values = self.channels.iter().map(|c| out.get(*c).to_f32());
        match protocol::encode_outputs_with(self.seq, out.t_us, values, self.channels.len(), &mut self.buf) {
            Some(len) => {
                self.len = len;
                self.pos = 0;
            }
            None => self.dropped = self.dropped.wrapping_add(1),
        }
        self.seq = self.seq.wrapping_add(1);
    }

    fn poll(&mut self) -> bool {
        while self.pos < self.len && matches!(self.tx.write_ready(), Ok(true)) {
            let rest = self.buf.get(self.pos..self.len).unwrap_or(&[]);
            match self.tx.write(rest) {
                Ok(n) if n > 0 => self.pos += n,
                _ => break,
            }
        }
        self.pos < self.len
    }
}
