//! Reading files with a bound: whole files into memory, gunzipped on the fly, never more than
//! the caller allows (a corrupt or hostile `.gz` must not exhaust memory).

use std::io::Read;
use std::path::Path;

use crate::error::{Error, Result};

/// What a bounded read found.
pub(crate) enum Bounded {
    /// The whole file (gunzipped), no more than the bound.
    Within(Vec<u8>),
    /// More than the bound: the file's size, gunzipped, when asked to count it (else the bound
    /// plus one).
    Over(u64),
}

/// Whether `path` names a gzipped file (`.gz`, in any case, as the formats' names are read).
pub(crate) fn is_gzipped(path: &Path) -> bool {
    path.extension()
        .is_some_and(|ext| ext.eq_ignore_ascii_case("gz"))
}

/// The bytes of the file at `path`, gunzipped on the fly when its name ends in `.gz`, or an
/// error when there are more than `max_bytes` of them (after decompression).
pub fn read_file(path: &Path, max_bytes: u64) -> Result<Vec<u8>> {
    match read_bounded(path, max_bytes, false)? {
        Bounded::Within(bytes) => Ok(bytes),
        Bounded::Over(_) => Err(Error::input(
            path,
            "file",
            format!("larger than {max_bytes} bytes (uncompressed): not read"),
        )),
    }
}

/// The file at `path`, gunzipped on the fly when its name ends in `.gz`, holding no more than
/// `max_bytes + 1` bytes in memory; with `count_excess`, a larger file is read to its end to tell
/// its size.
pub(crate) fn read_bounded(path: &Path, max_bytes: u64, count_excess: bool) -> Result<Bounded> {
    let metadata = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !metadata.is_file() {
        return Err(Error::input(path, "file", "not a regular file"));
    }
    if !is_gzipped(path) {
        if metadata.len() > max_bytes {
            return Ok(Bounded::Over(metadata.len()));
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
    let rest = if count_excess {
        std::io::copy(&mut decoder, &mut std::io::sink()).map_err(corrupt)?
    } else {
        0
    };
    Ok(Bounded::Over(bytes.len() as u64 + rest))
}
