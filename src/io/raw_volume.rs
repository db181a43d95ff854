//! Raw scalar volumes: no header, x fastest, then y, then z, multi-byte types little-endian,
//! optionally gzipped.

use std::path::Path;

use super::read::{is_gzipped, read_bounded, Bounded, Size};
use crate::error::{Error, Result};
use crate::surfels::volume::{voxel_count, Samples, Volume};

/// The type of one voxel; the names are those of scene files and of the data files' names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VoxelType {
    /// Unsigned 8-bit integer.
    Uint8,
    /// Unsigned 16-bit integer, little-endian.
    Uint16,
    /// Signed 16-bit integer, little-endian.
    Int16,
    /// IEEE 754 single precision, little-endian; every value must be finite.
    Float32,
}

impl VoxelType {
    /// Every voxel type, in the order messages list them.
    pub const ALL: [VoxelType; 4] = [
        VoxelType::Uint8,
        VoxelType::Uint16,
        VoxelType::Int16,
        VoxelType::Float32,
    ];

    /// The type called `name` in a scene file (`uint8`, `uint16`, `int16`, `float32`).
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|t| t.name() == name)
    }

    /// Its name in scene files.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            VoxelType::Uint8 => "uint8",
            VoxelType::Uint16 => "uint16",
            VoxelType::Int16 => "int16",
            VoxelType::Float32 => "float32",
        }
    }

    /// Bytes per voxel.
    #[must_use]
    pub fn size(self) -> usize {
        match self {
            VoxelType::Uint8 => 1,
            VoxelType::Uint16 | VoxelType::Int16 => 2,
            VoxelType::Float32 => 4,
        }
    }
}

/// How far past the expected size a gzipped volume's bytes are counted for the message that it
/// does not match (64 MiB, a fraction of a second to decompress): enough to tell a volume of
/// other dimensions by its size, while a small file that inflates a thousandfold is not
/// decompressed to its end.
const COUNTED_PAST_EXPECTED: u64 = 1 << 26;

/// Checks `dimensions` and returns the byte count a file of `voxel`s must have.
fn expected_bytes(path: &Path, dimensions: [usize; 3], voxel: VoxelType) -> Result<u64> {
    Ok(voxel_count(dimensions).map_err(|e| e.in_file(path, ""))? * voxel.size() as u64)
}

/// The error for a file that does not hold exactly the volume the scene describes: `found` bytes
/// (after decompression, for a gzipped file).
fn wrong_size(
    path: &Path,
    dimensions: [usize; 3],
    voxel: VoxelType,
    expected: u64,
    found: Size,
) -> Error {
    let [x, y, z] = dimensions;
    let after = if is_gzipped(path) {
        " after decompression"
    } else {
        ""
    };
    Error::input(
        path,
        "file size",
        format!(
            "expected {expected} bytes ({x} × {y} × {z} voxels of {}), found {found}{after}: the \
             file does not match the shape's dimensions and voxel type",
            voxel.name()
        ),
    )
}

impl Volume {
    /// Read a raw volume: no header, x fastest, then y, then z, multi-byte types little-endian.
    /// A path ending in `.gz` is gunzipped on the fly.
    ///
    /// Every problem is an error naming the file: a byte count other than the product of the
    /// dimensions and the voxel size (saying the expected and the found count), a zero dimension
    /// or more than [`crate::surfels::volume::MAX_VOXELS`] voxels, corrupt gzip data, and, for float32, a NaN or infinite
    /// voxel (the first one, by its (x, y, z) index).
    pub fn read(path: &Path, dimensions: [usize; 3], voxel: VoxelType) -> Result<Volume> {
        let expected = expected_bytes(path, dimensions, voxel)?;
        // Read no more than one byte past the expected size: a hostile file cannot fill memory,
        // and the rest is only counted for the message, up to [`COUNTED_PAST_EXPECTED`].
        let bytes = match read_bounded(path, expected, expected + COUNTED_PAST_EXPECTED)? {
            Bounded::Within(bytes) => bytes,
            Bounded::Over(size) => return Err(wrong_size(path, dimensions, voxel, expected, size)),
        };
        Volume::decode(bytes, dimensions, voxel, path)
    }

    /// Same as [`Volume::read`], from uncompressed bytes already in memory; `path` only names
    /// them in messages.
    pub fn parse(
        bytes: &[u8],
        dimensions: [usize; 3],
        voxel: VoxelType,
        path: &Path,
    ) -> Result<Volume> {
        Volume::decode(bytes.to_vec(), dimensions, voxel, path)
    }

    fn decode(
        bytes: Vec<u8>,
        dimensions: [usize; 3],
        voxel: VoxelType,
        path: &Path,
    ) -> Result<Volume> {
        let expected = expected_bytes(path, dimensions, voxel)?;
        if bytes.len() as u64 != expected {
            return Err(wrong_size(
                path,
                dimensions,
                voxel,
                expected,
                Size::Exact(bytes.len() as u64),
            ));
        }
        let samples = match voxel {
            VoxelType::Uint8 => Samples::Uint8(bytes),
            VoxelType::Uint16 => Samples::Uint16(
                bytes
                    .chunks_exact(2)
                    .map(|b| u16::from_le_bytes([b[0], b[1]]))
                    .collect(),
            ),
            VoxelType::Int16 => Samples::Int16(
                bytes
                    .chunks_exact(2)
                    .map(|b| i16::from_le_bytes([b[0], b[1]]))
                    .collect(),
            ),
            VoxelType::Float32 => Samples::Float32(
                bytes
                    .chunks_exact(4)
                    .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                    .collect(),
            ),
        };
        Volume::new(dimensions, samples).map_err(|e| e.in_file(path, ""))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surfels::volume::tests::{float_bytes, gzip, workdir};
    use glam::DVec3;

    #[test]
    fn voxel_types_decode_little_endian() {
        let path = Path::new("t.raw");
        let int16 = [-300i16, 5, 7, 9, 11, 13, 15, 1000];
        let bytes: Vec<u8> = int16.iter().flat_map(|v| v.to_le_bytes()).collect();
        let volume = Volume::parse(&bytes, [2; 3], VoxelType::Int16, path).unwrap();
        assert_eq!(volume.value_range(), (-300.0, 1000.0));
        let volume = Volume::parse(&bytes, [2; 3], VoxelType::Uint16, path).unwrap();
        assert_eq!(volume.value_range(), (5.0, 65236.0));
        assert_eq!(VoxelType::from_name("int32"), None);
        for t in VoxelType::ALL {
            assert_eq!(VoxelType::from_name(t.name()), Some(t));
        }
    }

    #[test]
    fn files_of_the_wrong_size_are_rejected_with_both_counts() {
        let dir = workdir("size");
        let bytes = vec![7u8; 4 * 5 * 6 * 2 - 1];
        std::fs::write(dir.join("short.raw"), &bytes).unwrap();
        std::fs::write(dir.join("short.raw.gz"), gzip(&bytes)).unwrap();
        std::fs::write(
            dir.join("long.raw.gz"),
            gzip(&[bytes.clone(), vec![0; 10]].concat()),
        )
        .unwrap();
        for (file, found) in [
            ("short.raw", "found 239"),
            ("short.raw.gz", "found 239 after decompression"),
            ("long.raw.gz", "found 249 after decompression"),
        ] {
            let message = Volume::read(&dir.join(file), [4, 5, 6], VoxelType::Int16)
                .unwrap_err()
                .to_string();
            assert!(
                message.contains(file)
                    && message.contains("expected 240 bytes")
                    && message.contains(found),
                "{message}"
            );
        }
        std::fs::write(dir.join("garbage.raw.gz"), b"not gzip at all").unwrap();
        let message = Volume::read(&dir.join("garbage.raw.gz"), [2; 3], VoxelType::Uint8)
            .unwrap_err()
            .to_string();
        assert!(message.contains("gzip data"), "{message}");
    }

    #[test]
    fn non_finite_float_voxels_are_named_by_index() {
        let dimensions = [6, 7, 8];
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let bytes = float_bytes(dimensions, DVec3::ONE, |p| {
                if p == DVec3::new(0.5, 1.0, 1.5) {
                    bad
                } else {
                    1.0
                }
            });
            let message = Volume::parse(&bytes, dimensions, VoxelType::Float32, Path::new("v.raw"))
                .unwrap_err()
                .to_string();
            assert!(message.contains("v.raw: voxel (3, 4, 5)"), "{message}");
        }
    }

    #[test]
    fn zero_and_oversized_dimensions_are_rejected() {
        let path = Path::new("v.raw");
        let message = Volume::parse(&[], [4, 0, 4], VoxelType::Uint8, path)
            .unwrap_err()
            .to_string();
        assert!(
            message.contains("dimensions") && message.contains("at least 1"),
            "{message}"
        );
        let message = Volume::read(path, [1 << 20, 1 << 20, 1 << 20], VoxelType::Uint8)
            .unwrap_err()
            .to_string();
        assert!(message.contains("limit of 2147483648 voxels"), "{message}");
        let message = Volume::read(path, [usize::MAX; 3], VoxelType::Float32)
            .unwrap_err()
            .to_string();
        assert!(message.contains("limit"), "{message}");
    }
}
