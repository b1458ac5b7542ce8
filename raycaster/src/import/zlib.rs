//! A zlib stream that holds a file's samples up to its end (MetaImage
//! `CompressedData = True`): bytes after the stream are an error, as they are
//! after gzip data, and the stream's length is checked against the header's
//! `CompressedDataSize` when it gives one (a file that lies about it is said so,
//! not read as far as it happens to decode).

use std::io::{BufRead, Read};

use super::ImportErrorKind;

/// Bytes after the stream are counted up to this many (beyond, "at least").
const TRAILING_COUNT_MAX: u64 = 64 << 20;

/// The decompressed bytes of the zlib stream in `R`, which must end `R`.
pub(crate) struct ZlibData<R: BufRead> {
    decoder: flate2::bufread::ZlibDecoder<Counted<R>>,
    /// The stream's length in bytes the header gives (`CompressedDataSize`).
    declared: Option<u64>,
    /// Whether the stream has ended (and its end was checked).
    ended: bool,
}

impl<R: BufRead> ZlibData<R> {
    /// The stream starting at `input`'s first byte, `declared` bytes long
    /// where the header says so.
    pub(crate) fn new(input: R, declared: Option<u64>) -> Self {
        ZlibData {
            decoder: flate2::bufread::ZlibDecoder::new(Counted {
                inner: input,
                consumed: 0,
            }),
            declared,
            ended: false,
        }
    }

    /// At the stream's end: the input must end too, and the stream's length
    /// be the one declared.
    fn check_end(&mut self) -> std::io::Result<()> {
        let input = self.decoder.get_mut();
        let length = input.consumed;
        let mut extra = 0u64;
        while extra < TRAILING_COUNT_MAX {
            let n = input.fill_buf()?.len();
            if n == 0 {
                break;
            }
            input.consume(n);
            extra += n as u64;
        }
        let kind = if extra > 0 {
            ImportErrorKind::AfterStream {
                stream: length,
                extra,
                at_least: extra >= TRAILING_COUNT_MAX,
                declared: self.declared,
            }
        } else {
            match self.declared {
                Some(declared) if declared != length => ImportErrorKind::CompressedSize {
                    declared,
                    actual: length,
                },
                _ => return Ok(()),
            }
        };
        Err(std::io::Error::new(std::io::ErrorKind::InvalidData, kind))
    }
}

impl<R: BufRead> Read for ZlibData<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.ended {
            return Ok(0);
        }
        let n = self.decoder.read(buf)?;
        if n == 0 && !buf.is_empty() {
            self.ended = true;
            self.check_end()?;
        }
        Ok(n)
    }
}

/// A reader that counts the bytes taken from it.
struct Counted<R> {
    inner: R,
    consumed: u64,
}

impl<R: BufRead> Read for Counted<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let available = self.fill_buf()?;
        let n = available.len().min(buf.len());
        buf[..n].copy_from_slice(&available[..n]);
        self.consume(n);
        Ok(n)
    }
}

impl<R: BufRead> BufRead for Counted<R> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        self.inner.fill_buf()
    }

    fn consume(&mut self, amount: usize) {
        self.consumed += amount as u64;
        self.inner.consume(amount);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn zlib(data: &[u8]) -> Vec<u8> {
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
        z.write_all(data).unwrap();
        z.finish().unwrap()
    }

    fn read(bytes: &[u8], declared: Option<u64>) -> Result<Vec<u8>, String> {
        let mut out = Vec::new();
        ZlibData::new(std::io::BufReader::with_capacity(5, bytes), declared)
            .read_to_end(&mut out)
            .map_err(|e| e.to_string())?;
        Ok(out)
    }

    #[test]
    fn the_stream_must_end_the_data_and_be_as_long_as_declared() {
        let data = b"samples of a volume, samples of a volume";
        let z = zlib(data);
        let len = z.len() as u64;
        assert_eq!(read(&z, None).unwrap(), data);
        assert_eq!(read(&z, Some(len)).unwrap(), data);
        let err = read(&z, Some(len + 10)).unwrap_err();
        assert!(
            err.contains(&format!("CompressedDataSize is {}", len + 10))
                && err.contains(&format!("{len} bytes long")),
            "{err}"
        );
        let err = read(&[z.clone(), b"xyz".to_vec()].concat(), None).unwrap_err();
        assert!(
            err.contains("3 bytes follow the zlib stream") && err.contains(&format!("{len} bytes")),
            "{err}"
        );
        // Even zeros: nothing is known to pad zlib data.
        let err = read(&[z.clone(), vec![0; 4]].concat(), Some(len)).unwrap_err();
        assert!(err.contains("4 bytes follow"), "{err}");
        let err = read(&z[..z.len() - 4], None).unwrap_err();
        assert!(err.contains("incomplete"), "a stream cut short: {err}");
    }
}
