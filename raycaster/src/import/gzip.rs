//! Gzip data as `gzip -d` reads it: members one after another, and zeros
//! after the last (the padding of a block written to tape or a fixed-size
//! record) ending the data rather than failing as a member that is not one.

use std::io::{BufRead, Read, Seek, SeekFrom};
use std::path::Path;

/// Whether the file at `path` holds gzip's magic bytes at byte `offset`.
pub(crate) fn gzip_magic_at(path: &Path, offset: u64) -> std::io::Result<bool> {
    let mut file = crate::files::open_regular(path)?;
    file.seek(SeekFrom::Start(offset))?;
    let mut magic = [0u8; 2];
    let n = file.take(2).read(&mut magic)?;
    Ok(n == 2 && magic == [0x1f, 0x8b])
}

/// The decompressed bytes of the gzip members in `R`.
pub(crate) struct GzipMembers<R: BufRead> {
    /// The member being read; `None` once the data has ended.
    member: Option<flate2::bufread::GzDecoder<R>>,
}

impl<R: BufRead> GzipMembers<R> {
    /// The members of `input`, from its first byte.
    pub(crate) fn new(input: R) -> Self {
        GzipMembers {
            member: Some(flate2::bufread::GzDecoder::new(input)),
        }
    }
}

impl<R: BufRead> Read for GzipMembers<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        loop {
            let Some(member) = self.member.as_mut() else {
                return Ok(0);
            };
            let n = member.read(buf)?;
            if n > 0 || buf.is_empty() {
                return Ok(n);
            }
            // The member ended: another, padding, or the end.
            let Some(mut input) = self.member.take().map(|m| m.into_inner()) else {
                return Ok(0);
            };
            if input.fill_buf()?.starts_with(&[0x1f, 0x8b]) {
                self.member = Some(flate2::bufread::GzDecoder::new(input));
                continue;
            }
            loop {
                let rest = input.fill_buf()?;
                if rest.is_empty() {
                    return Ok(0);
                }
                if rest.iter().any(|&b| b != 0) {
                    return Err(std::io::Error::new(
                        std::io::ErrorKind::InvalidData,
                        "bytes follow the gzip data that are neither gzip data nor zero padding",
                    ));
                }
                let n = rest.len();
                input.consume(n);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn gzip(data: &[u8]) -> Vec<u8> {
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        gz.write_all(data).unwrap();
        gz.finish().unwrap()
    }

    fn read(bytes: &[u8]) -> std::io::Result<Vec<u8>> {
        let mut out = Vec::new();
        GzipMembers::new(std::io::BufReader::with_capacity(7, bytes)).read_to_end(&mut out)?;
        Ok(out)
    }

    #[test]
    fn members_follow_each_other_and_zero_padding_ends_the_data() {
        let (a, b) = (gzip(b"first member, "), gzip(b"second"));
        assert_eq!(read(&a).unwrap(), b"first member, ");
        assert_eq!(
            read(&[a.clone(), b.clone()].concat()).unwrap(),
            b"first member, second"
        );
        let padded = [a.clone(), b, vec![0; 513]].concat();
        assert_eq!(read(&padded).unwrap(), b"first member, second");
        let garbage = [a.clone(), vec![0, 0, b'x']].concat();
        let err = read(&garbage).unwrap_err().to_string();
        assert!(err.contains("neither gzip data nor zero padding"), "{err}");
        assert!(read(&a[..a.len() - 3]).is_err(), "a member cut short");
        assert!(read(b"not gzip").is_err());
    }
}
