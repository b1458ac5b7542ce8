//! Per-pixel compositing states as bytes, to hand a band of unfinished pixels
//! from one process to the next (distributed rendering).
//!
//! Every compositor's state encodes to a fixed number of bytes, little endian,
//! floats by their bits, so a state decoded on another rank continues exactly
//! where it stopped.

use super::camera::PixelRect;
use super::compositor::{Compositor, CompositorJob};
use super::pixel::PixelState;

/// A compositing state that can travel as bytes.
pub(crate) trait StateCodec: Sized {
    /// Bytes per state.
    const BYTES: usize;
    /// Appends exactly [`Self::BYTES`] bytes.
    fn encode(&self, out: &mut Vec<u8>);
    /// Reads a state from [`Self::BYTES`] bytes written by [`Self::encode`].
    fn decode(bytes: &mut Reader<'_>) -> Self;
}

/// Reads little-endian fields from a byte slice of a known layout.
pub(crate) struct Reader<'a> {
    bytes: &'a [u8],
}

impl<'a> Reader<'a> {
    /// A reader at the start of `bytes`.
    pub fn new(bytes: &'a [u8]) -> Self {
        Reader { bytes }
    }

    fn take<const N: usize>(&mut self) -> [u8; N] {
        let (head, rest) = self.bytes.split_at(N);
        self.bytes = rest;
        head.try_into().expect("split at N")
    }

    /// The next `u32`.
    pub fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }

    /// The next `u16`.
    pub fn u16(&mut self) -> u16 {
        u16::from_le_bytes(self.take())
    }

    /// The next `f32` (by its bits).
    pub fn f32(&mut self) -> f32 {
        f32::from_bits(self.u32())
    }

    /// The next byte.
    pub fn u8(&mut self) -> u8 {
        self.take::<1>()[0]
    }
}

/// Appends `v`'s little-endian bytes.
pub(crate) fn put_u32(out: &mut Vec<u8>, v: u32) {
    out.extend_from_slice(&v.to_le_bytes());
}

/// Appends `v`'s bits.
pub(crate) fn put_f32(out: &mut Vec<u8>, v: f32) {
    put_u32(out, v.to_bits());
}

/// A compositor that keeps nothing per pixel.
impl StateCodec for () {
    const BYTES: usize = 0;
    fn encode(&self, _out: &mut Vec<u8>) {}
    fn decode(_bytes: &mut Reader<'_>) -> Self {}
}

impl<S: StateCodec> StateCodec for PixelState<S> {
    const BYTES: usize = S::BYTES + 5;

    fn encode(&self, out: &mut Vec<u8>) {
        self.acc.encode(out);
        put_u32(out, self.next_sample);
        out.push(u8::from(self.done));
    }

    fn decode(r: &mut Reader<'_>) -> Self {
        PixelState {
            acc: S::decode(r),
            next_sample: r.u32(),
            done: r.u8() != 0,
        }
    }
}

/// Asks a frame's compositor for the bytes of one pixel's state
/// (`plan.compositor.run(StateBytes)`).
pub(crate) struct StateBytes;

impl CompositorJob for StateBytes {
    type Output = usize;
    fn run<C: Compositor>(self, _c: &C) -> usize {
        <PixelState<C::State> as StateCodec>::BYTES
    }
}

/// Why bytes received from another process are not a state buffer.
#[derive(Debug, thiserror::Error)]
#[error("a band of pixel states is malformed: {0}")]
pub struct StateBufferError(String);

/// The compositing states of a rectangle of pixels, row by row, as bytes: what
/// one rank hands the next in a distributed frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StateBuffer {
    rect: PixelRect,
    record: usize,
    bytes: Vec<u8>,
}

/// Bytes before the records: the rectangle and the record size.
const HEADER: usize = 20;

impl StateBuffer {
    /// A buffer for `rect` with records of `record` bytes, zeroed.
    pub(crate) fn new(rect: PixelRect, record: usize) -> Self {
        StateBuffer {
            rect,
            record,
            bytes: vec![0; rect.area() as usize * record],
        }
    }

    /// The pixels it holds.
    pub fn rect(&self) -> PixelRect {
        self.rect
    }

    /// Bytes per pixel.
    pub fn record(&self) -> usize {
        self.record
    }

    /// The buffer as one message: a header (rectangle, record size) and the
    /// records.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(HEADER + self.bytes.len());
        for v in [self.rect.x0, self.rect.y0, self.rect.x1, self.rect.y1] {
            put_u32(&mut out, v);
        }
        put_u32(&mut out, self.record as u32);
        out.extend_from_slice(&self.bytes);
        out
    }

    /// A buffer from a message of [`Self::to_bytes`], checked against the
    /// rectangle and record size the receiver expects.
    pub fn from_bytes(
        mut message: Vec<u8>,
        rect: PixelRect,
        record: usize,
    ) -> Result<Self, StateBufferError> {
        if message.len() < HEADER {
            return Err(StateBufferError(format!(
                "{} bytes, shorter than its header",
                message.len()
            )));
        }
        let mut r = Reader::new(&message[..HEADER]);
        let got = PixelRect {
            x0: r.u32(),
            y0: r.u32(),
            x1: r.u32(),
            y1: r.u32(),
        };
        let got_record = r.u32() as usize;
        if got != rect || got_record != record {
            return Err(StateBufferError(format!(
                "holds {got:?} with {got_record}-byte states, expected {rect:?} with {record}"
            )));
        }
        let expected = HEADER + rect.area() as usize * record;
        if message.len() != expected {
            return Err(StateBufferError(format!(
                "{} bytes, expected {expected}",
                message.len()
            )));
        }
        message.drain(..HEADER);
        Ok(StateBuffer {
            rect,
            record,
            bytes: message,
        })
    }

    /// Byte offset of pixel `(x, y)` (inside the rectangle).
    fn offset(&self, x: u32, y: u32) -> usize {
        let w = (self.rect.x1 - self.rect.x0) as usize;
        ((y - self.rect.y0) as usize * w + (x - self.rect.x0) as usize) * self.record
    }

    /// Decodes the states of `rect` (inside the buffer) into `states`, row by row.
    pub(crate) fn read<S: StateCodec>(&self, rect: PixelRect, states: &mut [S]) {
        debug_assert_eq!(S::BYTES, self.record);
        let w = (rect.x1 - rect.x0) as usize;
        for (row, y) in (rect.y0..rect.y1).enumerate() {
            let start = self.offset(rect.x0, y);
            let mut r = Reader::new(&self.bytes[start..start + w * self.record]);
            for state in &mut states[row * w..(row + 1) * w] {
                *state = S::decode(&mut r);
            }
        }
    }

    /// Encodes `states` (of `rect`, inside the buffer, row by row) into place.
    pub(crate) fn write<S: StateCodec>(&mut self, rect: PixelRect, states: &[S]) {
        debug_assert_eq!(S::BYTES, self.record);
        let w = (rect.x1 - rect.x0) as usize;
        let mut row_bytes = Vec::with_capacity(w * self.record);
        for (row, y) in (rect.y0..rect.y1).enumerate() {
            row_bytes.clear();
            for state in &states[row * w..(row + 1) * w] {
                state.encode(&mut row_bytes);
            }
            let start = self.offset(rect.x0, y);
            self.bytes[start..start + row_bytes.len()].copy_from_slice(&row_bytes);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::local::Accumulation;

    #[test]
    fn states_survive_the_round_trip_bit_for_bit() {
        let rect = PixelRect {
            x0: 2,
            y0: 5,
            x1: 6,
            y1: 8,
        };
        let record = <PixelState<Accumulation> as StateCodec>::BYTES;
        let mut buffer = StateBuffer::new(rect, record);
        let states: Vec<PixelState<Accumulation>> = (0..rect.area())
            .map(|i| {
                let mut acc = Accumulation::starting_at(-0.0);
                acc.color = [i as f32 * 0.1, f32::MIN_POSITIVE, 1.0];
                acc.alpha = 0.3;
                acc.weight = i as f32 * 7.0;
                acc.depth = if i % 2 == 0 { f32::INFINITY } else { 2.5 };
                acc.next_index = u32::MAX - i as u32;
                acc.weighted_depth = -(i as f32);
                PixelState {
                    acc,
                    next_sample: i as u32,
                    done: i % 3 == 0,
                }
            })
            .collect();
        buffer.write(rect, &states);
        let received = StateBuffer::from_bytes(buffer.to_bytes(), rect, record).unwrap();
        let mut back = vec![PixelState::new(Accumulation::starting_at(0.0)); states.len()];
        received.read(rect, &mut back);
        assert_eq!(back, states);
        assert!(back[0].acc.value.is_sign_negative(), "bits, not values");
        // A message of another rectangle, size or length is refused.
        let mut other = rect;
        other.y1 += 1;
        assert!(StateBuffer::from_bytes(buffer.to_bytes(), other, record).is_err());
        assert!(StateBuffer::from_bytes(buffer.to_bytes(), rect, record + 1).is_err());
        let mut short = buffer.to_bytes();
        short.pop();
        assert!(StateBuffer::from_bytes(short, rect, record).is_err());
        assert!(StateBuffer::from_bytes(vec![1, 2, 3], rect, record).is_err());
    }
}
