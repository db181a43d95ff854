//! Triangle mesh files: Wavefront OBJ read here, PLY faces in [`super::ply`], a mesh read by its
//! file name, and a mesh written as OBJ or PLY ([`write_mesh`]).

use std::io::Write;
use std::path::Path;

use glam::DVec3;

use super::ply::parse_ply_mesh;
use super::read::{self, read_file};
use crate::error::{Error, Result};
use crate::surfels::mesh::{Mesh, MeshPart};

/// Largest mesh file read, after decompression: 2 GiB holds tens of millions of triangles, and a
/// bound keeps a corrupt or hostile `.gz` from exhausting memory.
pub const MAX_MESH_BYTES: u64 = 2 << 30;

/// The file formats a mesh is read from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    /// Wavefront OBJ.
    Obj,
    /// PLY with a face element.
    Ply,
}

impl MeshFormat {
    /// The format a file name says, ignoring case and a trailing `.gz`: `.obj` or `.ply`.
    #[must_use]
    pub fn of(path: &Path) -> Option<MeshFormat> {
        let name = path.file_name()?.to_str()?.to_ascii_lowercase();
        let name = name.strip_suffix(".gz").unwrap_or(&name);
        if name.ends_with(".obj") {
            Some(MeshFormat::Obj)
        } else if name.ends_with(".ply") {
            Some(MeshFormat::Ply)
        } else {
            None
        }
    }
}

impl Mesh {
    /// Read an OBJ or PLY mesh, as its name says (`.obj`, `.ply`, either optionally `.gz`, which
    /// is gunzipped on the fly). See [`parse_obj`] and [`super::ply::parse_ply_mesh`] for what is
    /// read; a file with no faces is an error too.
    pub fn read(path: &Path) -> Result<Mesh> {
        let format = MeshFormat::of(path).ok_or_else(|| {
            Error::input(
                path,
                "file name",
                "a mesh must be an .obj or a .ply file (optionally gzipped, .obj.gz or .ply.gz)",
            )
        })?;
        Mesh::parse(&read_file(path, MAX_MESH_BYTES)?, format, path)
    }

    /// Same as [`Mesh::read`], from uncompressed bytes already in memory; `path` only names them
    /// in messages.
    pub fn parse(bytes: &[u8], format: MeshFormat, path: &Path) -> Result<Mesh> {
        let mesh = match format {
            MeshFormat::Obj => parse_obj(bytes, path)?,
            MeshFormat::Ply => parse_ply_mesh(bytes, path)?,
        };
        if mesh.triangles.is_empty() {
            return Err(Error::input(
                path,
                "faces",
                format!(
                    "the file has {} vertices but no faces: a mesh needs triangles or polygons",
                    mesh.positions.len()
                ),
            ));
        }
        Ok(mesh)
    }
}

/// A mesh from Wavefront OBJ bytes already in memory (uncompressed; `path` only names them in
/// messages). Reads `v x y z` (a fourth number or vertex colours after it are ignored) and faces
/// `f` whose corners are `v`, `v/vt`, `v/vt/vn` or `v//vn`, counted from 1, or back from the
/// latest vertex when negative (−1 is the latest); a polygon is fan-triangulated around its
/// first corner. Comments (`#` to the end of the line), a UTF-8 byte order mark and every other
/// statement (`vn`, `vt`, `o`, `g`, `s`, `usemtl`, `l`, …) are skipped.
///
/// Every problem is an [`Error::Input`] naming the file and the line: a coordinate missing, not a
/// number or not finite, a face of fewer than 3 corners, a corner that is not a number, index 0,
/// or an index past the vertices the file defines.
pub fn parse_obj(bytes: &[u8], path: &Path) -> Result<Mesh> {
    let mut mesh = Mesh::default();
    // The largest positive index met and its line: faces may name vertices defined further down,
    // so the range check waits for the end of the file.
    let mut largest: Option<(u64, usize)> = None;
    let mut corners: Vec<u32> = Vec::new();
    // A UTF-8 byte order mark, which some editors write first, would be part of the first word.
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    for (number, raw_line) in bytes.split(|&b| b == b'\n').enumerate() {
        let line = number + 1;
        let error = |message: String| Error::input(path, format!("line {line}"), message);
        let text = raw_line.split(|&b| b == b'#').next().unwrap_or_default();
        let mut words = text
            .split(u8::is_ascii_whitespace)
            .filter(|word| !word.is_empty())
            .map(String::from_utf8_lossy);
        match words.next().as_deref() {
            Some("v") => {
                let mut xyz = [0.0; 3];
                for (value, axis) in xyz.iter_mut().zip(["x", "y", "z"]) {
                    let word = words.next().ok_or_else(|| {
                        error(format!("vertex without {axis}: expected `v x y z`"))
                    })?;
                    *value = word
                        .parse::<f64>()
                        .ok()
                        .filter(|v| v.is_finite())
                        .ok_or_else(|| {
                            error(format!(
                                "vertex {axis} is `{word}`; every coordinate must be a finite \
                                 number"
                            ))
                        })?;
                }
                MeshPart::Vertices
                    .check(mesh.positions.len() + 1, path, || format!("line {line}"))?;
                mesh.positions.push(DVec3::from_array(xyz));
            }
            Some("f") => {
                corners.clear();
                for word in words {
                    let reference = word.split('/').next().unwrap_or_default();
                    let index = reference.parse::<i64>().map_err(|_| {
                        error(format!(
                            "face corner `{word}` is not a vertex reference (`v`, `v/vt`, \
                             `v/vt/vn` or `v//vn`, whole numbers)"
                        ))
                    })?;
                    let defined = mesh.positions.len() as u64;
                    let resolved = match index {
                        0 => {
                            return Err(error(
                                "vertex index 0: OBJ counts vertices from 1 (or back from −1)"
                                    .into(),
                            ))
                        }
                        i if i > 0 => {
                            let i = i.unsigned_abs() - 1;
                            if largest.is_none_or(|(most, _)| i > most) {
                                largest = Some((i, line));
                            }
                            i
                        }
                        i => defined.checked_sub(i.unsigned_abs()).ok_or_else(|| {
                            error(format!(
                                "vertex index {i} counts back past the first vertex: {defined} \
                                 are defined above this line"
                            ))
                        })?,
                    };
                    // Past u32 it cannot be a vertex either; the range check at the end says so.
                    corners.push(u32::try_from(resolved).unwrap_or(u32::MAX));
                }
                if corners.len() < 3 {
                    return Err(error(format!(
                        "a face of {} corners: a face needs at least 3",
                        corners.len()
                    )));
                }
                let triangles = mesh.triangles.len() + corners.len() - 2;
                MeshPart::Triangles.check(triangles, path, || format!("line {line}"))?;
                // A fan around the first corner keeps the polygon's winding in every triangle.
                mesh.triangles.extend(
                    (1..corners.len() - 1).map(|k| [corners[0], corners[k], corners[k + 1]]),
                );
            }
            _ => {}
        }
    }
    let defined = mesh.positions.len() as u64;
    if let Some((index, line)) = largest.filter(|&(index, _)| index >= defined) {
        return Err(Error::input(
            path,
            format!("line {line}"),
            format!(
                "vertex index {} is out of range: the file defines {defined} vertices",
                index + 1
            ),
        ));
    }
    Ok(mesh)
}

/// Write `mesh` as a file its name says: Wavefront OBJ (`.obj`) or binary little-endian PLY
/// (`.ply`), positions as double. Errors name the file.
pub fn write_mesh(mesh: &Mesh, path: &Path) -> Result<()> {
    let format = MeshFormat::of(path)
        .filter(|_| !read::is_gzipped(path))
        .ok_or_else(|| {
            Error::input(
                path,
                "file name",
                "a mesh is written as .obj or .ply (not gzipped)",
            )
        })?;
    super::write::write_whole(path, |out| match format {
        MeshFormat::Obj => write_obj(mesh, out),
        MeshFormat::Ply => write_ply_mesh(mesh, out),
    })
    .map_err(|e| Error::input(path, "file", format!("cannot write it: {e}")))
}

/// `v x y z` per vertex (shortest text that reads back to the same double) and `f a b c` per
/// triangle, counted from 1.
fn write_obj(mesh: &Mesh, out: &mut impl Write) -> std::io::Result<()> {
    writeln!(out, "# written by streak")?;
    for p in &mesh.positions {
        writeln!(out, "v {} {} {}", p.x, p.y, p.z)?;
    }
    for t in &mesh.triangles {
        writeln!(out, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
    }
    Ok(())
}

/// Binary little-endian PLY: double x, y, z per vertex, a list of three uint per face.
fn write_ply_mesh(mesh: &Mesh, out: &mut impl Write) -> std::io::Result<()> {
    writeln!(
        out,
        "ply\nformat binary_little_endian 1.0\ncomment written by streak"
    )?;
    writeln!(out, "element vertex {}", mesh.positions.len())?;
    writeln!(
        out,
        "property double x\nproperty double y\nproperty double z"
    )?;
    writeln!(out, "element face {}", mesh.triangles.len())?;
    writeln!(out, "property list uchar uint vertex_indices\nend_header")?;
    for p in &mesh.positions {
        for c in p.to_array() {
            out.write_all(&c.to_le_bytes())?;
        }
    }
    for t in &mesh.triangles {
        out.write_all(&[3])?;
        for v in t {
            out.write_all(&v.to_le_bytes())?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surfels::mesh::tests::square;
    use std::io::Write;
    use std::path::PathBuf;

    const BAD: &str = "bad.obj";

    fn obj(text: &str) -> Result<Mesh> {
        parse_obj(text.as_bytes(), Path::new(BAD))
    }

    /// Parses `text`, expecting an error at `line`; returns the message.
    fn obj_error(text: &str, line: usize) -> String {
        let message = match obj(text) {
            Ok(mesh) => panic!("expected an error, got {} triangles", mesh.triangles.len()),
            Err(error) => error.to_string(),
        };
        let field = format!("{BAD}: line {line}: ");
        assert!(
            message.starts_with(&field),
            "`{message}` should start with `{field}`"
        );
        message
    }

    #[test]
    fn obj_reads_every_face_form() {
        let text = "# a comment\r\n\
            mtllib box.mtl\n\
            o square\n\
            v 0 0 0\n\
            v 1 0 0 1.0\n\
            v\t1 1 0 0.5 0.5 0.5\n\
            v 0 1 0\n\
            vt 0 0\nvt 1 0\nvt 1 1\n\
            vn 0 0 1\n\
            g sides\ns off\nusemtl grey\n\
            f 1 2 3\n\
            f 1/1 2/2 3/3  # trailing comment\n\
            f 1/1/1 2/2/1 3/3/1\r\n\
            f 1//1 2//1 3//1\n\
            f -4 -3 -2\n\
            f 1 2 3 4\n\
            l 1 2\n";
        let mesh = obj(text).unwrap();
        assert_eq!(mesh.positions.len(), 4);
        assert_eq!(mesh.positions[2], DVec3::new(1.0, 1.0, 0.0));
        let mut expected = vec![[0, 1, 2]; 5];
        expected.extend([[0, 1, 2], [0, 2, 3]]);
        assert_eq!(mesh.triangles, expected);
    }

    #[test]
    fn a_polygon_whose_fan_passes_the_triangle_bound_is_refused() {
        use crate::surfels::mesh::MAX_MESH_TRIANGLES;
        // Two bytes of text a corner, twelve bytes a triangle (more once drawn): one line of a
        // 67 MB file would make 2²⁵ + 1 triangles.
        let mut text = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\nf");
        text.push_str(&" 1".repeat(MAX_MESH_TRIANGLES + 3));
        let message = obj_error(&text, 4);
        assert!(
            message.contains("more than 33554432 triangles"),
            "{message}"
        );
    }

    #[test]
    fn a_byte_order_mark_before_the_first_statement_is_not_part_of_it() {
        // Editors on Windows may begin a UTF-8 file with U+FEFF; glued to the first `v`, it made
        // the word `\u{feff}v`, so that vertex was skipped and every face's indices shifted.
        let mesh = obj("\u{feff}v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n").unwrap();
        assert_eq!(mesh, square(1.0));
    }

    #[test]
    fn obj_faces_may_name_vertices_defined_later() {
        let mesh = obj("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap();
        assert_eq!(mesh.triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn obj_mistakes_are_errors_naming_the_line() {
        let three = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
        obj_error("v 0 0\n", 1);
        let message = obj_error(&format!("{three}v 1 nan 0\n"), 4);
        assert!(message.contains("vertex y is `nan`"), "{message}");
        obj_error(&format!("{three}v 1e999 0 0\n"), 4);
        obj_error(&format!("{three}v 1 zero 0\n"), 4);
        let message = obj_error(&format!("{three}f 1 2\n"), 4);
        assert!(message.contains("at least 3"), "{message}");
        obj_error(&format!("{three}f 0 1 2\n"), 4);
        obj_error(&format!("{three}f 1 2 x/1\n"), 4);
        obj_error(&format!("{three}f 1 2 3.5\n"), 4);
        let message = obj_error(&format!("{three}f -1 -2 -4\n"), 4);
        assert!(message.contains("3 are defined above"), "{message}");
        let message = obj_error(&format!("{three}f 1 2 3\nf 1 2 4\nf 1 2 3\n"), 5);
        assert!(message.contains("index 4 is out of range"), "{message}");
        obj_error(&format!("{three}f 1 2 99999999999\n"), 4);
    }

    #[test]
    fn files_without_faces_and_unknown_names_are_errors() {
        let path = Path::new("points.obj");
        let message = Mesh::parse(b"v 0 0 0\n", MeshFormat::Obj, path)
            .unwrap_err()
            .to_string();
        assert!(message.starts_with("points.obj: faces: "), "{message}");
        assert_eq!(
            MeshFormat::of(Path::new("a/B.OBJ.gz")),
            Some(MeshFormat::Obj)
        );
        assert_eq!(MeshFormat::of(Path::new("b.ply")), Some(MeshFormat::Ply));
        assert_eq!(MeshFormat::of(Path::new("c.stl")), None);
        let message = Mesh::read(Path::new("c.stl")).unwrap_err().to_string();
        assert!(message.starts_with("c.stl: file name: "), "{message}");
        let missing = Mesh::read(Path::new("/nonexistent/mesh.obj")).unwrap_err();
        assert!(matches!(missing, Error::Io { .. }));
    }

    #[test]
    fn gzipped_obj_and_ply_files_read_like_plain_ones() {
        let dir = std::env::temp_dir().join(format!("streak-mesh-gz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let obj_text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
        let ply_text = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\n\
            property float y\nproperty float z\nelement face 1\n\
            property list uchar int vertex_indices\nend_header\n\
            0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n";
        for (name, text) in [("square.obj.gz", obj_text), ("square.ply.gz", ply_text)] {
            let mut encoder =
                flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
            encoder.write_all(text.as_bytes()).unwrap();
            std::fs::write(dir.join(name), encoder.finish().unwrap()).unwrap();
            assert_eq!(Mesh::read(&dir.join(name)).unwrap(), square(1.0), "{name}");
        }
        std::fs::write(dir.join("broken.obj.gz"), b"\x1f\x8b\x08\x00 not gzip").unwrap();
        let message = Mesh::read(&dir.join("broken.obj.gz"))
            .unwrap_err()
            .to_string();
        assert!(message.contains("gzip data"), "{message}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A file the repository ships for tests (`tests/data`) or for the gallery (`gallery/data`).
    fn repository_data(relative: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join(relative)
    }

    #[test]
    fn the_bunny_reads_alike_from_obj_and_ply() {
        let from_ply =
            Mesh::read(&repository_data("gallery/data/bunny_bun_zipper.ply.gz")).unwrap();
        let from_obj =
            Mesh::read(&repository_data("tests/data/bunny_stanford-bunny.obj.gz")).unwrap();
        assert_eq!(from_ply.positions.len(), 35_947);
        assert_eq!(from_ply.triangles.len(), 69_451);
        assert_eq!(from_obj.triangles, from_ply.triangles);
        let worst = from_obj
            .positions
            .iter()
            .zip(&from_ply.positions)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0, f64::max);
        assert!(worst < 1e-6, "positions differ by up to {worst}");
    }

    #[test]
    fn real_meshes_read_with_their_counts() {
        // Binary little-endian, with a zero vertex normal that a mesh does not need.
        let dragon = Mesh::read(&repository_data("tests/data/dragon_100k.ply.gz")).unwrap();
        assert_eq!(
            (dragon.positions.len(), dragon.triangles.len()),
            (50_002, 100_000)
        );
        let armadillo = Mesh::read(&repository_data("gallery/data/armadillo_100k.obj.gz")).unwrap();
        assert_eq!(
            (armadillo.positions.len(), armadillo.triangles.len()),
            (49_990, 99_976)
        );
        // Closed and wound outward: the signed volume Σ a·(b×c)/6 is positive.
        for name in [
            "armadillo_100k.obj.gz",
            "fandisk.obj.gz",
            "rocker_arm.obj.gz",
        ] {
            let mesh = Mesh::read(&repository_data(&format!("gallery/data/{name}"))).unwrap();
            let volume: f64 = mesh
                .triangles
                .iter()
                .map(|t| {
                    let [a, b, c] = mesh.corners(*t).unwrap();
                    a.dot(b.cross(c)) / 6.0
                })
                .sum();
            assert!(volume > 0.0, "{name}: signed volume {volume}");
        }
    }
}
