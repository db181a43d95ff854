//! Reading files with a bound: whole files into memory, gunzipped on the fly, never more than
//! the caller allows (a corrupt or hostile `.gz` must not exhaust memory).

use std::io::Read;
use std::path::Path;

use crate::error::{Error, Result};

/// What a bounded read found.
pub(crate) enum Bounded {
    /// The whole file (gunzipped), no more than the bound.
    Within(Vec<u8>),
    /// More than the bound: the file's size (gunzipped), counted no further than the caller
    /// asked.
    Over(Size),
}

/// The size of a file read past its bound.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Size {
    /// Exactly this many bytes.
    Exact(u64),
    /// More than this many: counting stopped there.
    MoreThan(u64),
}

impl std::fmt::Display for Size {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Size::Exact(n) => write!(f, "{n}"),
            Size::MoreThan(n) => write!(f, "more than {n}"),
        }
    }
}

/// Whether `path` names a gzipped file (`.gz`, in any case, as the formats' names are read).
pub(crate) fn is_gzipped(path: &Path) -> bool {
    path.extension()
        .is_some_and(|ext| ext.eq_ignore_ascii_case("gz"))
}

/// The bytes of the file at `path`, gunzipped on the fly when its name ends in `.gz`, or an
/// error when there are more than `max_bytes` of them (after decompression).
pub fn read_file(path: &Path, max_bytes: u64) -> Result<Vec<u8>> {
    match read_bounded(path, max_bytes, 0)? {
        Bounded::Within(bytes) => Ok(bytes),
        Bounded::Over(_) => Err(Error::input(
            path,
            "file",
            format!("larger than {max_bytes} bytes (uncompressed): not read"),
        )),
    }
}

/// The text of the file at `path`, read as [`read_file`] reads it: at most `max_bytes`, and
/// UTF-8.
pub fn read_text(path: &Path, max_bytes: u64) -> Result<String> {
    String::from_utf8(read_file(path, max_bytes)?)
        .map_err(|e| Error::input(path, "file", format!("not UTF-8 text: {}", e.utf8_error())))
}

/// The file at `path`, gunzipped on the fly when its name ends in `.gz`, holding no more than
/// `max_bytes + 1` bytes in memory. A larger gzipped file is decompressed on to count its size
/// for the message, but no further than `count_to` bytes: a small `.gz` can hold a thousand
/// times its size, and counting all of it would take time without bound.
pub(crate) fn read_bounded(path: &Path, max_bytes: u64, count_to: u64) -> Result<Bounded> {
    let metadata = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !metadata.is_file() {
        return Err(Error::input(path, "file", "not a regular file"));
    }
    if !is_gzipped(path) {
        if metadata.len() > max_bytes {
            return Ok(Bounded::Over(Size::Exact(metadata.len())));
        }
        return std::fs::read(path)
            .map(Bounded::Within)
            .map_err(|e| Error::io(path, e));
    }
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut decoder = flate2::read::MultiGzDecoder::new(std::io::BufReader::new(file));
    let corrupt = |e: std::io::Error| {
        Error::input(
            path,
            "gzip data",
            format!("cannot decompress the file: {e}"),
        )
    };
    let mut bytes = Vec::new();
    (&mut decoder)
        .take(max_bytes + 1)
        .read_to_end(&mut bytes)
        .map_err(corrupt)?;
    if bytes.len() as u64 <= max_bytes {
        return Ok(Bounded::Within(bytes));
    }
    let read = bytes.len() as u64;
    let further = count_to.saturating_sub(read);
    let rest = std::io::copy(&mut (&mut decoder).take(further + 1), &mut std::io::sink())
        .map_err(corrupt)?;
    Ok(Bounded::Over(if rest > further {
        Size::MoreThan(read + further)
    } else {
        Size::Exact(read + rest)
    }))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::surfels::volume::tests::{gzip, workdir};

    /// The message `load` gives for a file of valid `text` padded with comment lines past
    /// `max_bytes`.
    pub(crate) fn refusal_past_size(
        text: &str,
        max_bytes: u64,
        load: impl Fn(&Path) -> Result<()>,
    ) -> String {
        let dir = workdir(&format!("past-{max_bytes}"));
        let path = dir.join("large.toml");
        let padding = "# a comment line of sixty-four bytes, repeated to fill the file\n";
        let lines = max_bytes as usize / padding.len() + 1;
        std::fs::write(&path, text.to_string() + &padding.repeat(lines)).unwrap();
        let message = load(&path).unwrap_err().to_string();
        std::fs::remove_dir_all(dir).unwrap();
        message
    }

    #[test]
    fn a_gzipped_file_past_its_bound_is_counted_only_as_far_as_asked() {
        // A `.gz` can inflate a thousandfold: counting it to its end would take time without
        // bound, so the count stops where the caller said and says so.
        let dir = workdir("bounded-read");
        let path = dir.join("zeros.raw.gz");
        std::fs::write(&path, gzip(&vec![0; 1000])).unwrap();
        let over = |count_to| match read_bounded(&path, 10, count_to).unwrap() {
            Bounded::Over(size) => size,
            Bounded::Within(_) => panic!("1,000 bytes read within a bound of 10"),
        };
        assert_eq!(over(100), Size::MoreThan(100));
        assert_eq!(over(999), Size::MoreThan(999));
        assert_eq!(over(1000), Size::Exact(1000));
        assert_eq!(over(0), Size::MoreThan(11));
        assert_eq!(Size::MoreThan(100).to_string(), "more than 100");
        match read_bounded(&path, 1000, 0).unwrap() {
            Bounded::Within(bytes) => assert_eq!(bytes.len(), 1000),
            Bounded::Over(size) => panic!("1,000 bytes over a bound of 1,000: {size}"),
        }
    }
}
