//! The values of a VTK XML `DataArray` in each encoding VTK's files use: `ascii` text, `binary`
//! (base64 inside the element) and `appended` (raw bytes or base64 in the file's
//! `<AppendedData>`), each binary block led by a header of `UInt32` or `UInt64` numbers, in
//! either byte order, uncompressed or as `vtkZLibDataCompressor` blocks.
//!
//! An uncompressed base64 block is read whether its header was encoded apart from its data (as
//! VTK writes it: the header's base64 ends in `=` padding) or together with it (as meshio
//! does). A compressed block's header `[blocks, block size, last block size, compressed
//! sizes…]` is encoded apart, its zlib streams together (both writers). Every error is a
//! message saying what is wrong; the caller names the file and the array.

use base64::Engine;
use base64::engine::general_purpose::STANDARD;
use std::io::Read;

/// A number type of VTK's XML files (`type="Float32"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Scalar {
    Int8,
    UInt8,
    Int16,
    UInt16,
    Int32,
    UInt32,
    Int64,
    UInt64,
    Float32,
    Float64,
}

/// One value of an array: integers exactly, floats as `f64`.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Number {
    Integer(i128),
    Float(f64),
}

impl Scalar {
    /// The type `name` names.
    pub(super) fn named(name: &str) -> Result<Self, String> {
        Ok(match name {
            "Int8" => Self::Int8,
            "UInt8" => Self::UInt8,
            "Int16" => Self::Int16,
            "UInt16" => Self::UInt16,
            "Int32" => Self::Int32,
            "UInt32" => Self::UInt32,
            "Int64" => Self::Int64,
            "UInt64" => Self::UInt64,
            "Float32" => Self::Float32,
            "Float64" => Self::Float64,
            other => {
                return Err(format!(
                    "type {other:?} is not read (Int8 to UInt64, Float32 or Float64)"
                ));
            }
        })
    }

    /// Bytes of one value.
    fn size(self) -> usize {
        match self {
            Self::Int8 | Self::UInt8 => 1,
            Self::Int16 | Self::UInt16 => 2,
            Self::Int32 | Self::UInt32 | Self::Float32 => 4,
            Self::Int64 | Self::UInt64 | Self::Float64 => 8,
        }
    }

    /// The value of the little-endian bytes `b` (`size()` of them).
    fn read(self, b: &[u8]) -> Number {
        let bytes = |b: &[u8]| -> [u8; 8] {
            let mut all = [0; 8];
            all[..b.len()].copy_from_slice(b);
            all
        };
        let wide = u64::from_le_bytes(bytes(b));
        match self {
            Self::Int8 => Number::Integer(b[0] as i8 as i128),
            Self::UInt8 => Number::Integer(b[0] as i128),
            Self::Int16 => Number::Integer(wide as u16 as i16 as i128),
            Self::UInt16 => Number::Integer(wide as u16 as i128),
            Self::Int32 => Number::Integer(wide as u32 as i32 as i128),
            Self::UInt32 => Number::Integer(wide as u32 as i128),
            Self::Int64 => Number::Integer(wide as i64 as i128),
            Self::UInt64 => Number::Integer(wide as i128),
            Self::Float32 => Number::Float(f32::from_bits(wide as u32) as f64),
            Self::Float64 => Number::Float(f64::from_bits(wide)),
        }
    }

    /// The little-endian bytes of the number `text` (an `ascii` array's value), if it is one of
    /// this type.
    fn parse(self, text: &str) -> Option<Vec<u8>> {
        match self {
            Self::Float32 => text.parse::<f32>().ok().map(|x| x.to_le_bytes().to_vec()),
            Self::Float64 => text.parse::<f64>().ok().map(|x| x.to_le_bytes().to_vec()),
            _ => {
                let x: i128 = text.parse().ok()?;
                let bits = 8 * self.size() as u32;
                let signed = matches!(self, Self::Int8 | Self::Int16 | Self::Int32 | Self::Int64);
                let (lo, hi) = match signed {
                    true => (-(1i128 << (bits - 1)), (1i128 << (bits - 1)) - 1),
                    false => (0, (1i128 << bits) - 1),
                };
                // Two's complement: the low bytes of an i128 in range are the value's.
                (lo..=hi)
                    .contains(&x)
                    .then(|| x.to_le_bytes()[..self.size()].to_vec())
            }
        }
    }
}

/// How a file stores its binary blocks: the attributes of its `<VTKFile>`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Encoding {
    /// `byte_order="BigEndian"` (else `LittleEndian`).
    pub big_endian: bool,
    /// Bytes of each number of a block's header: 4 (`header_type="UInt32"`, VTK's default) or
    /// 8 (`UInt64`).
    pub header_bytes: usize,
    /// `compressor="vtkZLibDataCompressor"`: every block is zlib streams.
    pub zlib: bool,
}

/// The values of one array, as little-endian bytes of its type (whatever the file's order).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Values {
    scalar: Scalar,
    bytes: Vec<u8>,
}

impl Values {
    /// The values of `bytes` in the file's byte order (`big_endian`).
    fn of(scalar: Scalar, mut bytes: Vec<u8>, big_endian: bool) -> Result<Self, String> {
        let size = scalar.size();
        if !bytes.len().is_multiple_of(size) {
            return Err(format!(
                "{} bytes is not a whole number of {scalar:?} values",
                bytes.len()
            ));
        }
        if big_endian {
            bytes.chunks_exact_mut(size).for_each(<[u8]>::reverse);
        }
        Ok(Self { scalar, bytes })
    }

    /// The number of values.
    pub fn len(&self) -> usize {
        self.bytes.len() / self.scalar.size()
    }

    fn numbers(&self) -> impl Iterator<Item = Number> + '_ {
        let scalar = self.scalar;
        self.bytes
            .chunks_exact(scalar.size())
            .map(move |b| scalar.read(b))
    }

    /// Every value as `f64` (exact but for 64-bit integers beyond 2^53).
    pub fn to_f64(&self) -> Vec<f64> {
        self.numbers()
            .map(|n| match n {
                Number::Integer(i) => i as f64,
                Number::Float(x) => x,
            })
            .collect()
    }

    /// Every value as an integer from 0 to `max`: an integer type's values, none out of range.
    pub fn to_unsigned(&self, max: u64) -> Result<Vec<u64>, String> {
        self.numbers()
            .enumerate()
            .map(|(k, n)| match n {
                Number::Integer(i) if (0..=max as i128).contains(&i) => Ok(i as u64),
                Number::Integer(i) => Err(format!("value {k} (0-based), {i}, is not in 0..={max}")),
                Number::Float(_) => Err(format!("{:?} is not an integer type", self.scalar)),
            })
            .collect()
    }
}

/// The values of an `ascii` array: numbers apart by white space.
pub(super) fn ascii(text: &str, scalar: Scalar) -> Result<Values, String> {
    let mut bytes = Vec::new();
    for (k, token) in text.split_ascii_whitespace().enumerate() {
        let value = scalar
            .parse(token)
            .ok_or_else(|| format!("value {k} (0-based), {token:?}, is not a {scalar:?}"))?;
        bytes.extend(value);
    }
    Values::of(scalar, bytes, false)
}

/// The values of a `binary` array, whose text is a base64 block (white space ignored).
pub(super) fn inline(text: &str, scalar: Scalar, encoding: Encoding) -> Result<Values, String> {
    let compact: Vec<u8> = text.bytes().filter(|b| !b.is_ascii_whitespace()).collect();
    Values::of(
        scalar,
        base64_block(&compact, encoding)?,
        encoding.big_endian,
    )
}

/// The values of an `appended` array: the block at `offset` of the appended data (the bytes
/// after its `_`), raw bytes or (`base64`) text.
pub(super) fn appended(
    data: &[u8],
    offset: usize,
    base64: bool,
    scalar: Scalar,
    encoding: Encoding,
) -> Result<Values, String> {
    let at = data.get(offset..).ok_or_else(|| {
        format!(
            "offset {offset} is past the end of the appended data ({} bytes)",
            data.len()
        )
    })?;
    let bytes = match base64 {
        true => base64_block(at, encoding)?,
        false => raw_block(at, encoding)?,
    };
    Values::of(scalar, bytes, encoding.big_endian)
}

/// The data of the raw block that starts `data`.
fn raw_block(data: &[u8], encoding: Encoding) -> Result<Vec<u8>, String> {
    let cut = || "the appended data ends inside a block".to_owned();
    let header = data.get(..header_len(data, encoding)?).ok_or_else(cut)?;
    let body = data.get(header.len()..).ok_or_else(cut)?;
    let body = body.get(..body_len(header, encoding)?).ok_or_else(cut)?;
    match encoding.zlib {
        true => inflate(header, body, encoding),
        false => Ok(body.to_vec()),
    }
}

/// The data of the base64 block that starts `text`.
fn base64_block(text: &[u8], encoding: Encoding) -> Result<Vec<u8>, String> {
    let h = encoding.header_bytes;
    // The first `bytes` bytes that the base64 from character `from` on encodes.
    let segment = |from: usize, bytes: usize| -> Result<Vec<u8>, String> {
        let cut = || "the base64 data ends inside a block".to_owned();
        let to = chars(bytes).and_then(|c| c.checked_add(from));
        let part = to.and_then(|to| text.get(from..to)).ok_or_else(cut)?;
        let mut decoded = STANDARD
            .decode(part)
            .map_err(|e| format!("bad base64: {e}"))?;
        match decoded.len() >= bytes {
            true => decoded.truncate(bytes),
            false => return Err(cut()),
        }
        Ok(decoded)
    };
    // A compressed header's first three numbers are whole base64 quanta (12 or 24 bytes).
    let first = segment(0, if encoding.zlib { 3 * h } else { h })?;
    let header_bytes = header_len(&first, encoding)?;
    let header = segment(0, header_bytes)?;
    let header_chars = chars(header_bytes).expect("the header decoded");
    let body_bytes = body_len(&header, encoding)?;
    if encoding.zlib {
        return inflate(&header, &segment(header_chars, body_bytes)?, encoding);
    }
    if text[header_chars - 1] == b'=' {
        // The header encoded apart from the data (VTK).
        return segment(header_chars, body_bytes);
    }
    // The header and the data encoded together (meshio).
    let together = h
        .checked_add(body_bytes)
        .ok_or("a block of too many bytes")?;
    Ok(segment(0, together)?.split_off(h))
}

/// Base64 characters of `bytes` bytes.
fn chars(bytes: usize) -> Option<usize> {
    bytes.div_ceil(3).checked_mul(4)
}

/// Number `k` of a block's header `header` (in the file's byte order).
fn header_number(header: &[u8], k: usize, encoding: Encoding) -> Result<usize, String> {
    let h = encoding.header_bytes;
    let b = header
        .get(k * h..(k + 1) * h)
        .ok_or("the data ends inside a block header")?;
    let mut all = [0; 8];
    match encoding.big_endian {
        true => all[8 - h..].copy_from_slice(b),
        false => all[..h].copy_from_slice(b),
    }
    let value = match encoding.big_endian {
        true => u64::from_be_bytes(all),
        false => u64::from_le_bytes(all),
    };
    usize::try_from(value).map_err(|_| format!("a block of {value} bytes is too large"))
}

/// Bytes of the header of the block whose header starts with `first`: one number
/// uncompressed, 3 plus one per zlib stream compressed.
fn header_len(first: &[u8], encoding: Encoding) -> Result<usize, String> {
    let h = encoding.header_bytes;
    match encoding.zlib {
        false => Ok(h),
        true => header_number(first, 0, encoding)?
            .checked_add(3)
            .and_then(|n| n.checked_mul(h))
            .ok_or_else(|| "a block header of too many streams".to_owned()),
    }
}

/// Bytes of the data that follows `header` in the file: the data, or its zlib streams.
fn body_len(header: &[u8], encoding: Encoding) -> Result<usize, String> {
    if !encoding.zlib {
        return header_number(header, 0, encoding);
    }
    let streams = header_number(header, 0, encoding)?;
    (0..streams).try_fold(0usize, |sum, k| {
        sum.checked_add(header_number(header, 3 + k, encoding)?)
            .ok_or_else(|| "compressed blocks of too many bytes".to_owned())
    })
}

/// The data of the zlib streams `body` that `header` describes: every stream inflates to the
/// block size, the last to the last block size where that is not 0.
fn inflate(header: &[u8], body: &[u8], encoding: Encoding) -> Result<Vec<u8>, String> {
    let streams = header_number(header, 0, encoding)?;
    let block = header_number(header, 1, encoding)?;
    let last = header_number(header, 2, encoding)?;
    let mut out = Vec::new();
    let mut at = 0usize;
    for k in 0..streams {
        let len = header_number(header, 3 + k, encoding)?;
        let stream = at
            .checked_add(len)
            .and_then(|end| body.get(at..end))
            .ok_or("the compressed data is shorter than its header says")?;
        at += len;
        let want = match k + 1 == streams && last != 0 {
            true => last,
            false => block,
        };
        let before = out.len();
        flate2::read::ZlibDecoder::new(stream)
            .take(want as u64 + 1)
            .read_to_end(&mut out)
            .map_err(|e| format!("zlib stream {k} (0-based): {e}"))?;
        if out.len() - before != want {
            return Err(format!(
                "zlib stream {k} (0-based) inflates to {} bytes, its header says {want}",
                out.len() - before
            ));
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use flate2::Compression;
    use flate2::write::ZlibEncoder;
    use std::io::Write;

    /// The header numbers `numbers` as `e` writes them.
    fn header(numbers: &[usize], e: Encoding) -> Vec<u8> {
        let one = |x: usize| match e.big_endian {
            true => (x as u64).to_be_bytes()[8 - e.header_bytes..].to_vec(),
            false => (x as u64).to_le_bytes()[..e.header_bytes].to_vec(),
        };
        numbers.iter().flat_map(|&x| one(x)).collect()
    }

    /// `data` as a block of `e`: its header, and its data or its zlib streams of `block` bytes
    /// (the last block's size 0 where it is whole, as VTK writes it).
    fn block(data: &[u8], e: Encoding, block: usize) -> (Vec<u8>, Vec<u8>) {
        if !e.zlib {
            return (header(&[data.len()], e), data.to_vec());
        }
        let streams: Vec<Vec<u8>> = data
            .chunks(block)
            .map(|chunk| {
                let mut z = ZlibEncoder::new(Vec::new(), Compression::default());
                z.write_all(chunk).unwrap();
                z.finish().unwrap()
            })
            .collect();
        let mut numbers = vec![streams.len(), block, data.len() % block];
        numbers.extend(streams.iter().map(Vec::len));
        (header(&numbers, e), streams.concat())
    }

    /// `text` broken into lines of 76 characters, as some writers wrap base64.
    fn wrapped(text: &str) -> String {
        let lines: Vec<&str> = text
            .as_bytes()
            .chunks(76)
            .map(|l| std::str::from_utf8(l).unwrap())
            .collect();
        format!("\n    {}\n  ", lines.join("\n    "))
    }

    #[test]
    fn every_binary_encoding_reads_back_the_same_values() {
        // 56 bytes: three zlib blocks of 16, a partial one of 8.
        let values = [0.0, -1.5, 1e-300, f64::MAX, 3.25, -0.0, 7.0];
        let bits: Vec<u64> = values.iter().map(|x: &f64| x.to_bits()).collect();
        let read = |v: Values| -> Vec<u64> { v.to_f64().iter().map(|x| x.to_bits()).collect() };
        for big_endian in [false, true] {
            for header_bytes in [4, 8] {
                for zlib in [false, true] {
                    let e = Encoding {
                        big_endian,
                        header_bytes,
                        zlib,
                    };
                    let data: Vec<u8> = (values.iter())
                        .flat_map(|x| match big_endian {
                            true => x.to_be_bytes(),
                            false => x.to_le_bytes(),
                        })
                        .collect();
                    let (head, body) = block(&data, e, 16);
                    let f64s = Scalar::Float64;
                    // Raw, after another array's five bytes.
                    let raw = [vec![9; 5], head.clone(), body.clone()].concat();
                    assert_eq!(
                        read(appended(&raw, 5, false, f64s, e).unwrap()),
                        bits,
                        "{e:?}"
                    );
                    // Base64, the header encoded apart (VTK), appended after other text and
                    // inline, wrapped.
                    let apart = STANDARD.encode(&head) + &STANDARD.encode(&body);
                    let after = format!("AAAA{apart}");
                    let got = appended(after.as_bytes(), 4, true, f64s, e).unwrap();
                    assert_eq!(read(got), bits, "{e:?}");
                    assert_eq!(
                        read(inline(&wrapped(&apart), f64s, e).unwrap()),
                        bits,
                        "{e:?}"
                    );
                    // Uncompressed, the header and data encoded together (meshio).
                    if !zlib {
                        let together = STANDARD.encode([head, body].concat());
                        let got = inline(&wrapped(&together), f64s, e).unwrap();
                        assert_eq!(read(got), bits, "{e:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn every_type_reads_in_ascii_and_binary_alike() {
        let e = Encoding {
            big_endian: true,
            header_bytes: 8,
            zlib: false,
        };
        let cases: [(&str, &str, &[u8], &[f64]); 10] = [
            ("Int8", "-128 127", &[0x80, 0x7f], &[-128.0, 127.0]),
            ("UInt8", "0 255", &[0, 255], &[0.0, 255.0]),
            ("Int16", "-2", &[0xff, 0xfe], &[-2.0]),
            ("UInt16", "513", &[2, 1], &[513.0]),
            ("Int32", "-1", &[0xff; 4], &[-1.0]),
            ("UInt32", "4294967295", &[0xff; 4], &[4294967295.0]),
            (
                "Int64",
                "-3",
                &[0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xfd],
                &[-3.0],
            ),
            ("UInt64", "1", &[0, 0, 0, 0, 0, 0, 0, 1], &[1.0]),
            (
                "Float32",
                "0.1",
                &[0x3d, 0xcc, 0xcc, 0xcd],
                &[0.1f32 as f64],
            ),
            (
                "Float64",
                "-0.5e1",
                &[0xc0, 0x14, 0, 0, 0, 0, 0, 0],
                &[-5.0],
            ),
        ];
        for (name, text, big_endian, want) in cases {
            let scalar = Scalar::named(name).unwrap();
            assert_eq!(ascii(text, scalar).unwrap().to_f64(), want, "{name}");
            let (head, body) = block(big_endian, e, 0);
            let raw = [head, body].concat();
            assert_eq!(
                appended(&raw, 0, false, scalar, e).unwrap().to_f64(),
                want,
                "{name}"
            );
        }
        // Out of the type's range, or not a number of it.
        for (name, text) in [
            ("Int8", "128"),
            ("UInt8", "-1"),
            ("UInt16", "65536"),
            ("Int32", "1.5"),
            ("Float32", "one"),
        ] {
            let e = ascii(text, Scalar::named(name).unwrap()).unwrap_err();
            assert!(e.contains(name) && e.contains(text), "{e}");
        }
        assert!(Scalar::named("Float16").unwrap_err().contains("Float16"));
    }

    #[test]
    fn integers_are_read_in_range_and_floats_are_not_integers() {
        let codes = ascii("0 7 255", Scalar::Int64).unwrap();
        assert_eq!(codes.to_unsigned(255).unwrap(), [0, 7, 255]);
        assert!(
            codes
                .to_unsigned(254)
                .unwrap_err()
                .contains("255, is not in 0..=254")
        );
        let negative = ascii("-1", Scalar::Int8).unwrap();
        assert!(negative.to_unsigned(255).unwrap_err().contains("-1"));
        let floats = ascii("1", Scalar::Float32).unwrap();
        assert!(
            floats
                .to_unsigned(255)
                .unwrap_err()
                .contains("not an integer type")
        );
    }

    #[test]
    fn broken_blocks_are_errors_not_panics() {
        let le = |zlib| Encoding {
            big_endian: false,
            header_bytes: 8,
            zlib,
        };
        let data: Vec<u8> = (0..40).collect();
        let (head, body) = block(&data, le(true), 16);
        let whole = [head.clone(), body.clone()].concat();
        assert_eq!(
            appended(&whole, 0, false, Scalar::UInt8, le(true))
                .unwrap()
                .to_f64()
                .len(),
            40
        );
        // Cut anywhere: in the header, in the streams.
        for cut in [0, 7, 20, head.len(), whole.len() - 1] {
            let e = appended(&whole[..cut], 0, false, Scalar::UInt8, le(true)).unwrap_err();
            assert!(e.contains("ends inside"), "{cut}: {e}");
        }
        // A header claiming more than the file holds, or than any memory.
        let huge = [header(&[usize::MAX], le(false)), vec![1, 2]].concat();
        let e = appended(&huge, 0, false, Scalar::UInt8, le(false)).unwrap_err();
        assert!(e.contains("ends inside"), "{e}");
        let streams = [header(&[usize::MAX, 16, 0], le(true)), vec![0; 24]].concat();
        assert!(appended(&streams, 0, false, Scalar::UInt8, le(true)).is_err());
        // A stream that inflates to more (or less) than its block size says.
        let mut wrong = head.clone();
        wrong[8..16].copy_from_slice(&8u64.to_le_bytes());
        let e = appended(
            &[wrong, body.clone()].concat(),
            0,
            false,
            Scalar::UInt8,
            le(true),
        )
        .unwrap_err();
        assert!(e.contains("inflates to 9 bytes, its header says 8"), "{e}");
        // Damaged zlib data.
        let mut damaged = body;
        damaged[3] ^= 0x55;
        let e = appended(&[head, damaged].concat(), 0, false, Scalar::UInt8, le(true)).unwrap_err();
        assert!(e.contains("zlib"), "{e}");
        // Bytes that are no whole number of values; an offset past the data.
        let odd = [header(&[3], le(false)), vec![1, 2, 3]].concat();
        let e = appended(&odd, 0, false, Scalar::Float32, le(false)).unwrap_err();
        assert!(e.contains("3 bytes"), "{e}");
        assert!(
            appended(&odd, 99, false, Scalar::UInt8, le(false))
                .unwrap_err()
                .contains("offset 99")
        );
    }
}
