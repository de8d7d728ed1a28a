//! Consistent Overhead Byte Stuffing (Cheshire & Baker, 1999): removes every
//! 0x00 from a frame so 0x00 can delimit frames on the wire. Each run of up
//! to 254 non-zero bytes is preceded by a code byte `n` = 1 + run length;
//! `n < 0xFF` means a zero followed the run in the original data (except at
//! the very end), `n = 0xFF` means a maximal run with no zero after it.
//! Overhead: one byte per 254 bytes, plus one.

/// Why a COBS frame could not be decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CobsError {
    /// A 0x00 inside the encoded data.
    ZeroInFrame,
    /// A code byte points past the end of the frame.
    Truncated,
    /// The output buffer is too small.
    OutputFull,
}

impl core::fmt::Display for CobsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            CobsError::ZeroInFrame => "a 0x00 inside the encoded data",
            CobsError::Truncated => "a code byte points past the end of the frame",
            CobsError::OutputFull => "the output buffer is too small",
        })
    }
}

impl core::error::Error for CobsError {}

/// Maximum encoded length of `n` bytes.
pub const fn max_encoded_len(n: usize) -> usize {
    n + n / 254 + 1
}

/// Encodes `src` into `dst` (no trailing delimiter). Returns the length.
pub fn encode(src: &[u8], dst: &mut [u8]) -> Result<usize, CobsError> {
    if dst.len() < max_encoded_len(src.len()) {
        return Err(CobsError::OutputFull);
    }
    let mut code_at = 0usize;
    let mut out = 1usize;
    let mut code = 1u8;
    for &b in src {
        if b == 0 {
            *dst.get_mut(code_at).ok_or(CobsError::OutputFull)? = code;
            code_at = out;
            out += 1;
            code = 1;
        } else {
            *dst.get_mut(out).ok_or(CobsError::OutputFull)? = b;
            out += 1;
            code += 1;
            if code == 0xFF {
                *dst.get_mut(code_at).ok_or(CobsError::OutputFull)? = code;
                code_at = out;
                out += 1;
                code = 1;
            }
        }
    }
    *dst.get_mut(code_at).ok_or(CobsError::OutputFull)? = code;
    Ok(out)
}

/// Decodes `src` (without delimiter) into `dst`. Returns the length.
pub fn decode(src: &[u8], dst: &mut [u8]) -> Result<usize, CobsError> {
    let mut i = 0usize;
    let mut out = 0usize;
    while i < src.len() {
        let code = src.get(i).copied().ok_or(CobsError::Truncated)?;
        if code == 0 {
            return Err(CobsError::ZeroInFrame);
        }
        i += 1;
        let run = usize::from(code) - 1;
        let chunk = src.get(i..i + run).ok_or(CobsError::Truncated)?;
        if chunk.contains(&0) {
            return Err(CobsError::ZeroInFrame);
        }
        dst.get_mut(out..out + run)
            .ok_or(CobsError::OutputFull)?
            .copy_from_slice(chunk);
        out += run;
        i += run;
        if code != 0xFF && i < src.len() {
            *dst.get_mut(out).ok_or(CobsError::OutputFull)? = 0;
            out += 1;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn roundtrip(data: &[u8]) -> std::vec::Vec<u8> {
        let mut enc = std::vec![0u8; max_encoded_len(data.len())];
        let n = encode(data, &mut enc).unwrap();
        assert!(!enc[..n].contains(&0), "zero in encoding of {data:?}");
        let mut dec = std::vec![0u8; data.len() + 1];
        let m = decode(&enc[..n], &mut dec).unwrap();
        assert_eq!(&dec[..m], data);
        enc[..n].to_vec()
    }

    #[test]
    fn known_encodings() {
        // Examples worked by hand from the algorithm's definition.
        assert_eq!(roundtrip(&[]), [1]);
        assert_eq!(roundtrip(&[0]), [1, 1]);
        assert_eq!(roundtrip(&[0, 0]), [1, 1, 1]);
        assert_eq!(roundtrip(&[0x11, 0x22, 0, 0x33]), [3, 0x11, 0x22, 2, 0x33]);
        assert_eq!(
            roundtrip(&[0x11, 0x22, 0x33, 0x44]),
            [5, 0x11, 0x22, 0x33, 0x44]
        );
        assert_eq!(roundtrip(&[0x11, 0, 0, 0]), [2, 0x11, 1, 1, 1]);
    }

    #[test]
    fn long_runs_use_0xff_blocks() {
        let data: std::vec::Vec<u8> = (1..=254u8).collect();
        let enc = roundtrip(&data);
        assert_eq!(enc[0], 0xFF);
        assert_eq!(enc.len(), 256);
        let data: std::vec::Vec<u8> = (0..600).map(|i| (i % 255 + 1) as u8).collect();
        roundtrip(&data);
    }

    #[test]
    fn malformed_input_is_an_error() {
        let mut out = [0u8; 16];
        assert_eq!(decode(&[5, 1, 2], &mut out), Err(CobsError::Truncated));
        assert_eq!(decode(&[3, 1, 0, 4], &mut out), Err(CobsError::ZeroInFrame));
        assert_eq!(decode(&[0], &mut out), Err(CobsError::ZeroInFrame));
        assert_eq!(
            decode(&[4, 1, 2, 3], &mut [0u8; 2]),
            Err(CobsError::OutputFull)
        );
    }
}
