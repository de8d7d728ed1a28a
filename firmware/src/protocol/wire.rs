//! The field codec: how each field type of a message is laid out on the
//! wire. Little-endian integers, IEEE 754 binary32 floats, fixed-length
//! arrays, and two composite types (the estimation law and the error code).
//! Every type has one fixed length, so every message has one.

use super::ErrorCode;
use crate::estimate::{LinearLaw, PlaneLaw, QuadraticLaw};

/// Why a field could not be read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FieldError {
    /// The payload ended inside the field.
    Short,
    /// An enumeration byte outside its enumeration (a law kind, an error
    /// code).
    BadEnum,
}

impl core::fmt::Display for FieldError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            FieldError::Short => "the payload ends inside a field",
            FieldError::BadEnum => "an enumeration byte outside its enumeration",
        })
    }
}

impl core::error::Error for FieldError {}

/// Writes fields into a payload buffer; every write checks the bound.
pub struct Writer<'a> {
    buf: &'a mut [u8],
    at: usize,
}

impl<'a> Writer<'a> {
    /// A writer at the start of `buf`.
    pub fn new(buf: &'a mut [u8]) -> Self {
        Self { buf, at: 0 }
    }

    /// Bytes written so far.
    pub fn len(&self) -> usize {
        self.at
    }

    /// True when nothing has been written.
    pub fn is_empty(&self) -> bool {
        self.at == 0
    }

    /// Appends raw bytes; `None` when they do not fit.
    pub fn put(&mut self, bytes: &[u8]) -> Option<()> {
        let end = self.at.checked_add(bytes.len())?;
        self.buf.get_mut(self.at..end)?.copy_from_slice(bytes);
        self.at = end;
        Some(())
    }
}

/// Reads fields from a payload.
pub struct Reader<'a> {
    buf: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    /// A reader at the start of `buf`.
    pub fn new(buf: &'a [u8]) -> Self {
        Self { buf, at: 0 }
    }

    /// The next `N` bytes.
    pub fn take<const N: usize>(&mut self) -> Result<[u8; N], FieldError> {
        let end = self.at.checked_add(N).ok_or(FieldError::Short)?;
        let bytes = self.buf.get(self.at..end).ok_or(FieldError::Short)?;
        self.at = end;
        bytes.try_into().map_err(|_| FieldError::Short)
    }
}

/// A field type with one fixed wire length.
pub trait Wire: Sized + Copy {
    /// Bytes on the wire.
    const LEN: usize;
    /// How `docs/protocol.md` names the element type (`u8`, `f32`, `law`).
    const DOC_TYPE: &'static str;
    /// Elements: 1, or N for an array `[T; N]` (written `name[N]` in the
    /// docs).
    const COUNT: usize = 1;
    /// Appends the field.
    fn put(&self, w: &mut Writer<'_>) -> Option<()>;
    /// Reads the field.
    fn get(r: &mut Reader<'_>) -> Result<Self, FieldError>;
}

macro_rules! le_number {
    ($($t:ty),*) => {$(
        impl Wire for $t {
            const LEN: usize = core::mem::size_of::<$t>();
            const DOC_TYPE: &'static str = stringify!($t);
            fn put(&self, w: &mut Writer<'_>) -> Option<()> {
                w.put(&self.to_le_bytes())
            }
            fn get(r: &mut Reader<'_>) -> Result<Self, FieldError> {
                r.take().map(<$t>::from_le_bytes)
            }
        }
    )*};
}
le_number!(u8, u16, i16, u32, i32, f32);

impl<T: Wire + Default, const N: usize> Wire for [T; N] {
    const LEN: usize = T::LEN * N;
    const DOC_TYPE: &'static str = T::DOC_TYPE;
    const COUNT: usize = N;
    fn put(&self, w: &mut Writer<'_>) -> Option<()> {
        self.iter().try_for_each(|v| v.put(w))
    }
    fn get(r: &mut Reader<'_>) -> Result<Self, FieldError> {
        let mut out = [T::default(); N];
        for v in out.iter_mut() {
            *v = T::get(r)?;
        }
        Ok(out)
    }
}

impl Wire for ErrorCode {
    const LEN: usize = 1;
    const DOC_TYPE: &'static str = "u8";
    fn put(&self, w: &mut Writer<'_>) -> Option<()> {
        (*self as u8).put(w)
    }
    fn get(r: &mut Reader<'_>) -> Result<Self, FieldError> {
        ErrorCode::from_u8(u8::get(r)?).ok_or(FieldError::BadEnum)
    }
}

/// The estimation law (docs/protocol.md §4.4): kind, plus, minus and single
/// sensor bytes, then `[gain, offset, a, b, c, threshold, hysteresis]` as
/// f32, unused fields 0.
impl Wire for PlaneLaw {
    const LEN: usize = 4 + 7 * 4;
    const DOC_TYPE: &'static str = "law";
    fn put(&self, w: &mut Writer<'_>) -> Option<()> {
        let (kind, plus, minus, sensor, f) = match *self {
            PlaneLaw::Single { sensor, law } => {
                (0u8, 0, 0, sensor, [0.0, 0.0, law.a, law.b, law.c, 0.0, 0.0])
            }
            PlaneLaw::Differential { plus, minus, law } => (
                1,
                plus,
                minus,
                0,
                [law.gain, law.offset, 0.0, 0.0, 0.0, 0.0, 0.0],
            ),
            PlaneLaw::Switching {
                plus,
                minus,
                high,
                sensor,
                low,
                threshold_deg,
                hysteresis_deg,
            } => (
                2,
                plus,
                minus,
                sensor,
                [
                    high.gain,
                    high.offset,
                    low.a,
                    low.b,
                    low.c,
                    threshold_deg,
                    hysteresis_deg,
                ],
            ),
        };
        [kind, plus, minus, sensor].put(w)?;
        f.put(w)
    }
    fn get(r: &mut Reader<'_>) -> Result<Self, FieldError> {
        let [kind, plus, minus, sensor] = <[u8; 4]>::get(r)?;
        let [gain, offset, a, b, c, threshold_deg, hysteresis_deg] = <[f32; 7]>::get(r)?;
        let high = LinearLaw { gain, offset };
        let low = QuadraticLaw { a, b, c };
        Ok(match kind {
            0 => PlaneLaw::Single { sensor, law: low },
            1 => PlaneLaw::Differential {
                plus,
                minus,
                law: high,
            },
            2 => PlaneLaw::Switching {
                plus,
                minus,
                high,
                sensor,
                low,
                threshold_deg,
                hysteresis_deg,
            },
            _ => return Err(FieldError::BadEnum),
        })
    }
}
