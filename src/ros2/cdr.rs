//! The CDR encoding of ROS 2 messages: XCDR1 (plain CDR), little-endian, as `rmw` serializes
//! them for rosbag2 (`serialization_format: cdr`).
//!
//! A message starts with the 4-byte encapsulation header `00 01 00 00` (CDR_LE). Every
//! primitive is aligned to its own size (at most 8) counted from the end of that header, with
//! zero padding; a string is a u32 length that counts its terminating NUL, the bytes and the
//! NUL; a sequence is a u32 element count and the elements; a fixed array is its elements alone.

use crate::error::{Error, Result};

/// The encapsulation header of little-endian plain CDR.
pub const ENCAPSULATION_CDR_LE: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// Writes one message in CDR into a byte buffer that may be reused between messages.
///
/// ```
/// use psns::ros2::cdr::CdrWriter;
/// let mut w = CdrWriter::new();
/// w.u8(7);
/// w.u32(1); // aligned to 4 after the header: three zero bytes of padding
/// w.string("ab").unwrap();
/// assert_eq!(
///     w.into_bytes(),
///     [0, 1, 0, 0, 7, 0, 0, 0, 1, 0, 0, 0, 3, 0, 0, 0, b'a', b'b', 0]
/// );
/// ```
#[derive(Clone, Debug)]
pub struct CdrWriter {
    buf: Vec<u8>,
}

impl Default for CdrWriter {
    fn default() -> Self {
        Self::new()
    }
}

impl CdrWriter {
    /// An empty message (the encapsulation header only).
    pub fn new() -> Self {
        Self::with_buffer(Vec::new())
    }

    /// An empty message in `buf`'s allocation (its contents are dropped).
    pub fn with_buffer(mut buf: Vec<u8>) -> Self {
        buf.clear();
        buf.extend_from_slice(&ENCAPSULATION_CDR_LE);
        CdrWriter { buf }
    }

    /// Reserves room for `n` more bytes.
    pub fn reserve(&mut self, n: usize) {
        self.buf.reserve(n);
    }

    /// Bytes written after the encapsulation header (the origin of alignment).
    pub fn position(&self) -> usize {
        self.buf.len() - ENCAPSULATION_CDR_LE.len()
    }

    /// Zero padding up to the next multiple of `n` bytes after the header.
    fn align(&mut self, n: usize) {
        let r = self.position() % n;
        if r != 0 {
            self.buf.resize(self.buf.len() + n - r, 0);
        }
    }

    /// `uint8` (also `byte`, `char`).
    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }

    /// `bool`: one byte, 0 or 1.
    pub fn bool(&mut self, v: bool) {
        self.buf.push(v as u8);
    }

    /// `uint32`.
    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// `int32`.
    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// `float32`.
    pub fn f32(&mut self, v: f32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// `float64`.
    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// The u32 length (or element count) in front of a string or sequence.
    fn length(&mut self, n: usize, what: &str) -> Result<()> {
        let n = u32::try_from(n).map_err(|_| {
            Error::Invalid(format!(
                "CDR {what} of {n} elements is too long (at most {})",
                u32::MAX
            ))
        })?;
        self.u32(n);
        Ok(())
    }

    /// `string`: UTF-8 without NUL.
    pub fn string(&mut self, s: &str) -> Result<()> {
        if s.contains('\0') {
            return Err(Error::Invalid(format!(
                "CDR string {s:?} contains a NUL character"
            )));
        }
        self.length(s.len() + 1, "string")?;
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
        Ok(())
    }

    /// `uint8[]` (an unbounded sequence of bytes).
    pub fn byte_seq(&mut self, b: &[u8]) -> Result<()> {
        self.byte_seq_len(b.len())?;
        self.buf.extend_from_slice(b);
        Ok(())
    }

    /// The front of a `uint8[]` of `n` bytes, its element count: the bytes follow it, where
    /// the caller puts them (a message's bytes in front of pixels that stay where they are).
    ///
    /// ```
    /// use psns::ros2::cdr::CdrWriter;
    /// let (mut a, mut b) = (CdrWriter::new(), CdrWriter::new());
    /// a.u8(1);
    /// a.byte_seq(&[7, 8, 9]).unwrap();
    /// b.u8(1);
    /// b.byte_seq_len(3).unwrap();
    /// assert_eq!([b.as_bytes(), &[7, 8, 9]].concat(), a.into_bytes());
    /// ```
    pub fn byte_seq_len(&mut self, n: usize) -> Result<()> {
        self.length(n, "sequence")
    }

    /// The element count in front of an unbounded sequence of structures; the elements follow.
    pub fn seq_len(&mut self, n: usize) -> Result<()> {
        self.length(n, "sequence")
    }

    /// `float64[]` (an unbounded sequence).
    pub fn f64_seq(&mut self, v: &[f64]) -> Result<()> {
        self.length(v.len(), "sequence")?;
        self.f64_array(v);
        Ok(())
    }

    /// `float64[N]` (a fixed array: the elements alone).
    pub fn f64_array(&mut self, v: &[f64]) {
        for &x in v {
            self.f64(x);
        }
    }

    /// The message bytes, header included.
    pub fn into_bytes(self) -> Vec<u8> {
        self.buf
    }

    /// The message bytes so far, header included.
    pub fn as_bytes(&self) -> &[u8] {
        &self.buf
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// One primitive write, for the alignment property.
    #[derive(Clone, Debug)]
    enum Op {
        U8(u8),
        Bool(bool),
        U32(u32),
        I32(i32),
        F32(f32),
        F64(f64),
        Str(String),
        Bytes(Vec<u8>),
        F64Seq(Vec<f64>),
    }

    fn op() -> impl Strategy<Value = Op> {
        prop_oneof![
            any::<u8>().prop_map(Op::U8),
            any::<bool>().prop_map(Op::Bool),
            any::<u32>().prop_map(Op::U32),
            any::<i32>().prop_map(Op::I32),
            any::<f32>().prop_map(Op::F32),
            any::<f64>().prop_map(Op::F64),
            "[a-z_/]{0,9}".prop_map(Op::Str),
            proptest::collection::vec(any::<u8>(), 0..9).prop_map(Op::Bytes),
            proptest::collection::vec(any::<f64>(), 0..4).prop_map(Op::F64Seq),
        ]
    }

    /// A reader of the same rules, written from the specification: each primitive at a
    /// multiple of its size after the header, with zero padding before it.
    struct Reader<'a> {
        b: &'a [u8],
        pos: usize,
    }

    impl Reader<'_> {
        fn take(&mut self, size: usize, align: usize) -> &[u8] {
            while !(self.pos - 4).is_multiple_of(align) {
                assert_eq!(
                    self.b[self.pos], 0,
                    "padding byte at {} is not zero",
                    self.pos
                );
                self.pos += 1;
            }
            let s = &self.b[self.pos..self.pos + size];
            self.pos += size;
            s
        }
        fn u32(&mut self) -> u32 {
            u32::from_le_bytes(self.take(4, 4).try_into().unwrap())
        }
        fn f64(&mut self) -> f64 {
            f64::from_le_bytes(self.take(8, 8).try_into().unwrap())
        }
    }

    proptest! {
        /// Any sequence of writes reads back with the specification's alignment, the padding
        /// is zero and nothing follows the last value.
        #[test]
        fn every_primitive_is_aligned_to_its_size(ops in proptest::collection::vec(op(), 0..24)) {
            let mut w = CdrWriter::with_buffer(vec![9; 7]);
            for o in &ops {
                match o {
                    Op::U8(v) => w.u8(*v),
                    Op::Bool(v) => w.bool(*v),
                    Op::U32(v) => w.u32(*v),
                    Op::I32(v) => w.i32(*v),
                    Op::F32(v) => w.f32(*v),
                    Op::F64(v) => w.f64(*v),
                    Op::Str(s) => w.string(s).unwrap(),
                    Op::Bytes(b) => w.byte_seq(b).unwrap(),
                    Op::F64Seq(v) => w.f64_seq(v).unwrap(),
                }
            }
            let b = w.into_bytes();
            prop_assert_eq!(&b[..4], &ENCAPSULATION_CDR_LE);
            let mut r = Reader { b: &b, pos: 4 };
            for o in &ops {
                match o {
                    Op::U8(v) => prop_assert_eq!(r.take(1, 1)[0], *v),
                    Op::Bool(v) => prop_assert_eq!(r.take(1, 1)[0], *v as u8),
                    Op::U32(v) => prop_assert_eq!(r.u32(), *v),
                    Op::I32(v) => prop_assert_eq!(i32::from_le_bytes(r.take(4, 4).try_into().unwrap()), *v),
                    Op::F32(v) => prop_assert_eq!(r.take(4, 4), &v.to_le_bytes()[..]),
                    Op::F64(v) => prop_assert_eq!(r.f64().to_bits(), v.to_bits()),
                    Op::Str(s) => {
                        prop_assert_eq!(r.u32() as usize, s.len() + 1);
                        prop_assert_eq!(r.take(s.len(), 1), s.as_bytes());
                        prop_assert_eq!(r.take(1, 1)[0], 0);
                    }
                    Op::Bytes(v) => {
                        prop_assert_eq!(r.u32() as usize, v.len());
                        prop_assert_eq!(r.take(v.len(), 1), &v[..]);
                    }
                    Op::F64Seq(v) => {
                        prop_assert_eq!(r.u32() as usize, v.len());
                        for x in v {
                            prop_assert_eq!(r.f64().to_bits(), x.to_bits());
                        }
                    }
                }
            }
            prop_assert_eq!(r.pos, b.len());
        }
    }

    #[test]
    fn alignment_counts_from_after_the_header() {
        // an f64 right after the header needs no padding: offset 0 of the payload
        let mut w = CdrWriter::new();
        w.f64(1.0);
        assert_eq!(w.as_bytes().len(), 12);
        // after one byte, seven bytes of padding (not three, as counting from the file would)
        let mut w = CdrWriter::new();
        w.u8(1);
        w.f64(1.0);
        assert_eq!(w.as_bytes().len(), 4 + 8 + 8);
        assert_eq!(&w.as_bytes()[5..12], &[0; 7]);
    }

    #[test]
    fn bad_strings_are_refused() {
        let e = CdrWriter::new().string("a\0b").unwrap_err();
        assert!(e.is_usage() && e.to_string().contains("NUL"), "{e}");
    }
}
