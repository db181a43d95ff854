//! PLY files: point clouds read and written, and a PLY mesh's faces read for
//! [`crate::surfels::mesh`].

use std::io::Write;
use std::path::Path;

use glam::DVec3;

use super::image::srgb_to_linear;
use super::read::read_file;
use crate::error::{Error, Result};
use crate::surfels::cloud::PointCloud;
use crate::surfels::mesh::{Mesh, MeshPart};

// ---------------------------------------------------------------------------------------------
// PLY reading
// ---------------------------------------------------------------------------------------------

/// Read a PLY point cloud (ascii, binary_little_endian, binary_big_endian). A path ending in `.gz`
/// is gunzipped on the fly. Faces and other elements are ignored. Vertex properties: `x y z`
/// (required), `nx ny nz` (optional, all three or none), `red green blue` (optional, uchar or
/// float/double) and `radius` (optional); others are ignored. Any numeric PLY type is accepted
/// for positions, normals and radii.
///
/// Every problem is an [`Error::Input`] naming the file and the header line, element or vertex
/// (counted from 0) and property: a malformed or truncated file, values that are not finite, a
/// normal of zero length (normals are scaled to unit length), a radius that is not positive, a
/// float colour outside [0, 1].
pub fn read_ply(path: &Path) -> Result<PointCloud> {
    read_ply_checked(path, |_| Ok(()))
}

/// [`read_ply`], handing `check` the number of points the header declares (at least as many as
/// the cloud will hold) before the body is read, so that a cloud too large for its use is
/// refused before memory is spent on its points.
pub(crate) fn read_ply_checked(
    path: &Path,
    check: impl FnOnce(usize) -> Result<()>,
) -> Result<PointCloud> {
    parse_checked(&read_file(path, MAX_PLY_BYTES)?, path, check)
}

/// Largest PLY file read, after decompression: 2 GiB holds tens of millions of points, and a
/// bound keeps a corrupt or hostile `.gz` from exhausting memory.
pub const MAX_PLY_BYTES: u64 = 2 << 30;

/// Same as [`read_ply`], from uncompressed bytes already in memory; `path` is only used for error
/// messages.
pub fn parse_ply(bytes: &[u8], path: &Path) -> Result<PointCloud> {
    parse_checked(bytes, path, |_| Ok(()))
}

/// [`parse_ply`], with the declared point count passed to `check` first.
fn parse_checked(
    bytes: &[u8],
    path: &Path,
    check: impl FnOnce(usize) -> Result<()>,
) -> Result<PointCloud> {
    let header = parse_header(bytes, path)?;
    let vertex_element = vertex_element(&header, path)?;
    let vertices = &header.elements[vertex_element];
    check(vertices.count)?;
    let layout = VertexLayout::new(vertices, path)?;
    let mut reader = BodyReader::new(&header, bytes);
    for element in &header.elements[..vertex_element] {
        reader.skip_element(element, path)?;
    }
    read_vertices(&mut reader, vertices, &layout, path)
}

/// A triangle mesh from PLY bytes already in memory (uncompressed; `path` only names them in
/// messages): the vertices' `x y z` and the faces' vertex lists (`element face` with a list
/// property `vertex_indices` or `vertex_index`, any integer count and item types), each polygon
/// fan-triangulated. Other vertex properties (normals included) and other elements are ignored.
///
/// Every problem is an [`Error::Input`] naming the file and the header line, element or record:
/// the problems [`parse_ply`] reports for positions, no face element or no vertex list in it, a
/// face of fewer than 3 vertices, a vertex index that is negative or not below the vertex count.
pub fn parse_ply_mesh(bytes: &[u8], path: &Path) -> Result<Mesh> {
    let header = parse_header(bytes, path)?;
    let vertex_element = vertex_element(&header, path)?;
    let vertices = &header.elements[vertex_element];
    MeshPart::Vertices.check(vertices.count, path, || "element vertex".into())?;
    let layout = VertexLayout {
        position: position_properties(vertices, path)?,
        normal: None,
        color: None,
        radius: None,
    };
    let (face_element, list) = face_list(&header, path)?;
    // Every face is at least one triangle.
    MeshPart::Triangles.check(header.elements[face_element].count, path, || {
        "element face".into()
    })?;
    let mut reader = BodyReader::new(&header, bytes);
    let mut mesh = Mesh::default();
    let last = vertex_element.max(face_element);
    for (index, element) in header.elements[..=last].iter().enumerate() {
        if index == vertex_element {
            mesh.positions = read_vertices(&mut reader, vertices, &layout, path)?.positions;
        } else if index == face_element {
            mesh.triangles = read_faces(&mut reader, element, list, vertices.count, path)?;
        } else {
            reader.skip_element(element, path)?;
        }
    }
    Ok(mesh)
}

/// The index of the `vertex` element, which must declare at least one vertex.
fn vertex_element(header: &Header, path: &Path) -> Result<usize> {
    let index = header
        .elements
        .iter()
        .position(|element| element.name == "vertex")
        .ok_or_else(|| {
            Error::input(
                path,
                "element vertex",
                "the header declares no vertex element; a point cloud or mesh needs `element \
                 vertex N` with properties x, y and z",
            )
        })?;
    if header.elements[index].count == 0 {
        return Err(Error::input(
            path,
            "element vertex",
            "the header declares 0 vertices; the file holds no points",
        ));
    }
    Ok(index)
}

/// The index of the `face` element and of its vertex-index list property.
fn face_list(header: &Header, path: &Path) -> Result<(usize, usize)> {
    let element = header
        .elements
        .iter()
        .position(|element| element.name == "face")
        .ok_or_else(|| {
            Error::input(
                path,
                "element face",
                "the header declares no face element, so the file holds no mesh (for a point \
                 cloud use the shape type \"ply\")",
            )
        })?;
    let faces = &header.elements[element];
    let list = faces
        .properties
        .iter()
        .position(|p| p.name == "vertex_indices" || p.name == "vertex_index")
        .ok_or_else(|| {
            Error::input(
                path,
                "element face",
                "no property `vertex_indices` (or `vertex_index`): expected e.g. \
                 `property list uchar int vertex_indices`",
            )
        })?;
    let property = &faces.properties[list];
    match property.ty {
        PropertyType::List { item, .. } if item.integer_range().is_some() => Ok((element, list)),
        PropertyType::List { item, .. } => Err(Error::input(
            path,
            "element face",
            format!(
                "list `{}` holds {} items; vertex indices must be integers",
                property.name,
                item.name()
            ),
        )),
        PropertyType::Scalar(_) => Err(Error::input(
            path,
            "element face",
            format!(
                "property `{}` is a single number; expected a list of vertex indices",
                property.name
            ),
        )),
    }
}

/// Reads every record of the vertex element through `layout`.
fn read_vertices(
    reader: &mut BodyReader,
    vertices: &ElementDecl,
    layout: &VertexLayout,
    path: &Path,
) -> Result<PointCloud> {
    let mut cloud = CloudBuilder::new(layout, reader.capacity(vertices));
    let mut record = Record::new(vertices, None);
    for index in 0..vertices.count {
        if !reader.read_record(vertices, index, &mut record, path)? {
            return Err(Error::input(
                path,
                "element vertex",
                format!(
                    "the header declares {} vertices but the data ends after {index} \
                     (truncated file, or wrong count in the header)",
                    vertices.count
                ),
            ));
        }
        cloud.push(layout, vertices, index, &record.values, path)?;
    }
    Ok(cloud.finish())
}

/// Reads every record of the face element, fan-triangulating the polygons of list property
/// `list`, whose indices must be below `vertex_count`.
fn read_faces(
    reader: &mut BodyReader,
    faces: &ElementDecl,
    list: usize,
    vertex_count: usize,
    path: &Path,
) -> Result<Vec<[u32; 3]>> {
    let mut triangles = Vec::with_capacity(reader.capacity(faces));
    let mut record = Record::new(faces, Some(list));
    let property = &faces.properties[list];
    for index in 0..faces.count {
        if !reader.read_record(faces, index, &mut record, path)? {
            return Err(Error::input(
                path,
                "element face",
                format!(
                    "the header declares {} faces but the data ends after {index} (truncated \
                     file, or wrong count in the header)",
                    faces.count
                ),
            ));
        }
        let corners = &record.list;
        let field = || record_field(faces, index, property);
        if corners.len() < 3 {
            return Err(Error::input(
                path,
                field(),
                format!(
                    "a face of {} vertices: a face needs at least 3",
                    corners.len()
                ),
            ));
        }
        if let Some(bad) = corners
            .iter()
            .find(|&&v| !(v >= 0.0 && v < vertex_count as f64))
        {
            return Err(Error::input(
                path,
                field(),
                format!(
                    "vertex index {bad} is out of range: the file has {vertex_count} vertices, \
                     numbered from 0"
                ),
            ));
        }
        MeshPart::Triangles.check(triangles.len() + corners.len() - 2, path, field)?;
        // A polygon is cut into a fan around its first corner; the corners keep their order, so
        // every triangle keeps the polygon's winding.
        let corner = |k: usize| corners[k] as u32;
        triangles.extend((1..corners.len() - 1).map(|k| [corner(0), corner(k), corner(k + 1)]));
    }
    Ok(triangles)
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Encoding {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ScalarType {
    Int8,
    UInt8,
    Int16,
    UInt16,
    Int32,
    UInt32,
    Float32,
    Float64,
}

impl ScalarType {
    fn from_name(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => ScalarType::Int8,
            "uchar" | "uint8" => ScalarType::UInt8,
            "short" | "int16" => ScalarType::Int16,
            "ushort" | "uint16" => ScalarType::UInt16,
            "int" | "int32" => ScalarType::Int32,
            "uint" | "uint32" => ScalarType::UInt32,
            "float" | "float32" => ScalarType::Float32,
            "double" | "float64" => ScalarType::Float64,
            _ => return None,
        })
    }

    fn name(self) -> &'static str {
        match self {
            ScalarType::Int8 => "char",
            ScalarType::UInt8 => "uchar",
            ScalarType::Int16 => "short",
            ScalarType::UInt16 => "ushort",
            ScalarType::Int32 => "int",
            ScalarType::UInt32 => "uint",
            ScalarType::Float32 => "float",
            ScalarType::Float64 => "double",
        }
    }

    fn size(self) -> usize {
        match self {
            ScalarType::Int8 | ScalarType::UInt8 => 1,
            ScalarType::Int16 | ScalarType::UInt16 => 2,
            ScalarType::Int32 | ScalarType::UInt32 | ScalarType::Float32 => 4,
            ScalarType::Float64 => 8,
        }
    }

    /// Inclusive value range of an integer type; `None` for floating-point types.
    fn integer_range(self) -> Option<(i64, i64)> {
        match self {
            ScalarType::Int8 => Some((i8::MIN.into(), i8::MAX.into())),
            ScalarType::UInt8 => Some((0, u8::MAX.into())),
            ScalarType::Int16 => Some((i16::MIN.into(), i16::MAX.into())),
            ScalarType::UInt16 => Some((0, u16::MAX.into())),
            ScalarType::Int32 => Some((i32::MIN.into(), i32::MAX.into())),
            ScalarType::UInt32 => Some((0, u32::MAX.into())),
            ScalarType::Float32 | ScalarType::Float64 => None,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PropertyType {
    Scalar(ScalarType),
    List { count: ScalarType, item: ScalarType },
}

#[derive(Debug)]
struct PropertyDecl {
    name: String,
    ty: PropertyType,
}

#[derive(Debug)]
struct ElementDecl {
    name: String,
    count: usize,
    properties: Vec<PropertyDecl>,
}

#[derive(Debug)]
struct Header {
    encoding: Encoding,
    elements: Vec<ElementDecl>,
    /// Byte offset of the first byte after `end_header` and its line break.
    body_offset: usize,
    /// Line number (1-based) of the first body line, for ascii error messages.
    body_first_line: usize,
}

fn parse_header(bytes: &[u8], path: &Path) -> Result<Header> {
    if bytes.is_empty() {
        return Err(Error::input(
            path,
            "header line 1",
            "the file is empty; a PLY file starts with the line `ply`",
        ));
    }
    let mut encoding = None;
    let mut elements: Vec<ElementDecl> = Vec::new();
    let mut offset = 0;
    let mut line_number = 0;
    while offset < bytes.len() {
        line_number += 1;
        let line_end = bytes[offset..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |i| offset + i);
        let raw_line = &bytes[offset..line_end];
        offset = (line_end + 1).min(bytes.len());
        let field = format!("header line {line_number}");

        if line_number == 1 {
            if raw_line.strip_suffix(b"\r").unwrap_or(raw_line) != b"ply" {
                let hint = if bytes.starts_with(&[0x1f, 0x8b]) {
                    " (it looks gzip-compressed: name it *.gz to have it decompressed)"
                } else {
                    ""
                };
                return Err(Error::input(
                    path,
                    field,
                    format!("not a PLY file: the first line must be `ply`{hint}"),
                ));
            }
            continue;
        }
        let line = std::str::from_utf8(raw_line)
            .map_err(|_| Error::input(path, &field, "the header must be plain ASCII text"))?;
        let words: Vec<&str> = line.split_ascii_whitespace().collect();
        match words.as_slice() {
            [] | ["comment", ..] | ["obj_info", ..] => {}
            ["format", kind, _version] => {
                encoding = Some(match *kind {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::BinaryLittleEndian,
                    "binary_big_endian" => Encoding::BinaryBigEndian,
                    other => {
                        return Err(Error::input(
                            path,
                            field,
                            format!(
                                "unknown format `{other}`; expected ascii, \
                                 binary_little_endian or binary_big_endian"
                            ),
                        ))
                    }
                });
            }
            ["format", ..] => {
                return Err(Error::input(
                    path,
                    field,
                    "expected `format <ascii|binary_little_endian|binary_big_endian> 1.0`",
                ))
            }
            ["element", name, count] => {
                let count = count.parse::<usize>().map_err(|_| {
                    Error::input(
                        path,
                        &field,
                        format!("element count `{count}` is not a non-negative whole number"),
                    )
                })?;
                if elements.iter().any(|element| element.name == *name) {
                    return Err(Error::input(
                        path,
                        field,
                        format!("element `{name}` is declared twice"),
                    ));
                }
                elements.push(ElementDecl {
                    name: name.to_string(),
                    count,
                    properties: Vec::new(),
                });
            }
            ["element", ..] => {
                return Err(Error::input(
                    path,
                    field,
                    "expected `element <name> <count>`",
                ))
            }
            ["property", rest @ ..] => {
                let property = parse_property(rest, path, &field)?;
                let element = elements.last_mut().ok_or_else(|| {
                    Error::input(path, &field, "a property comes before any element")
                })?;
                if element.properties.iter().any(|p| p.name == property.name) {
                    return Err(Error::input(
                        path,
                        field,
                        format!(
                            "property `{}` is declared twice in element `{}`",
                            property.name, element.name
                        ),
                    ));
                }
                element.properties.push(property);
            }
            ["end_header"] => {
                let encoding = encoding.ok_or_else(|| {
                    Error::input(
                        path,
                        "header",
                        "no `format` line; expected e.g. `format binary_little_endian 1.0`",
                    )
                })?;
                return Ok(Header {
                    encoding,
                    elements,
                    body_offset: offset,
                    body_first_line: line_number + 1,
                });
            }
            [keyword, ..] => {
                return Err(Error::input(
                    path,
                    field,
                    format!(
                        "unknown header keyword `{keyword}`; expected format, element, \
                         property, comment, obj_info or end_header"
                    ),
                ))
            }
        }
    }
    Err(Error::input(
        path,
        "header",
        "the header has no `end_header` line (truncated or not a PLY file)",
    ))
}

fn parse_property(words: &[&str], path: &Path, field: &str) -> Result<PropertyDecl> {
    let scalar = |name: &str| {
        ScalarType::from_name(name).ok_or_else(|| {
            Error::input(
                path,
                field,
                format!(
                    "unknown property type `{name}`; expected char, uchar, short, ushort, int, \
                     uint, float or double (or int8 … float64)"
                ),
            )
        })
    };
    match words {
        ["list", count, item, name] => {
            let count = scalar(count)?;
            if count.integer_range().is_none() {
                return Err(Error::input(
                    path,
                    field,
                    format!(
                        "list `{name}` has a non-integer count type `{}`",
                        count.name()
                    ),
                ));
            }
            Ok(PropertyDecl {
                name: name.to_string(),
                ty: PropertyType::List {
                    count,
                    item: scalar(item)?,
                },
            })
        }
        [ty, name] => Ok(PropertyDecl {
            name: name.to_string(),
            ty: PropertyType::Scalar(scalar(ty)?),
        }),
        _ => Err(Error::input(
            path,
            field,
            "expected `property <type> <name>` or `property list <count type> <item type> <name>`",
        )),
    }
}

/// How an 8-bit or floating-point colour channel becomes linear RGB.
#[derive(Clone, Copy, Debug)]
enum ColorEncoding {
    Srgb8,
    Linear,
}

/// Which vertex properties hold what, as indices into the element's property list.
struct VertexLayout {
    position: [usize; 3],
    normal: Option<[usize; 3]>,
    color: Option<[(usize, ColorEncoding); 3]>,
    radius: Option<usize>,
}

impl VertexLayout {
    fn new(vertices: &ElementDecl, path: &Path) -> Result<Self> {
        let group = |names, what| find_group(vertices, names, what, path);
        let indices = |group: [(usize, ScalarType); 3]| group.map(|(index, _)| index);
        let position = position_properties(vertices, path)?;
        let normal = group(["nx", "ny", "nz"], "normal")?.map(indices);
        let color = match group(["red", "green", "blue"], "colour")? {
            None => None,
            Some(channels) => {
                let encoding_of = |(index, ty): (usize, ScalarType)| match ty {
                    ScalarType::UInt8 => Ok((index, ColorEncoding::Srgb8)),
                    ScalarType::Float32 | ScalarType::Float64 => Ok((index, ColorEncoding::Linear)),
                    other => Err(Error::input(
                        path,
                        "element vertex",
                        format!(
                            "colour property `{}` has type {}; expected uchar (sRGB 0–255) or \
                             float/double (linear 0–1)",
                            vertices.properties[index].name,
                            other.name()
                        ),
                    )),
                };
                Some([
                    encoding_of(channels[0])?,
                    encoding_of(channels[1])?,
                    encoding_of(channels[2])?,
                ])
            }
        };
        let radius = find_number(vertices, "radius", path)?.map(|(index, _)| index);
        Ok(VertexLayout {
            position,
            normal,
            color,
            radius,
        })
    }
}

/// The vertex property called `name` and its type, if there is one; a list is an error.
fn find_number(
    vertices: &ElementDecl,
    name: &str,
    path: &Path,
) -> Result<Option<(usize, ScalarType)>> {
    let Some(index) = vertices.properties.iter().position(|p| p.name == name) else {
        return Ok(None);
    };
    match vertices.properties[index].ty {
        PropertyType::Scalar(ty) => Ok(Some((index, ty))),
        PropertyType::List { .. } => Err(Error::input(
            path,
            "element vertex",
            format!("property `{name}` is a list; expected a single number"),
        )),
    }
}

/// All of a group's vertex properties, none of them, or an error naming what is missing.
fn find_group(
    vertices: &ElementDecl,
    names: [&str; 3],
    what: &str,
    path: &Path,
) -> Result<Option<[(usize, ScalarType); 3]>> {
    let found = [
        find_number(vertices, names[0], path)?,
        find_number(vertices, names[1], path)?,
        find_number(vertices, names[2], path)?,
    ];
    match found {
        [Some(a), Some(b), Some(c)] => Ok(Some([a, b, c])),
        [None, None, None] => Ok(None),
        _ => {
            let missing: Vec<&str> = names
                .iter()
                .zip(found)
                .filter(|(_, found)| found.is_none())
                .map(|(name, _)| *name)
                .collect();
            Err(Error::input(
                path,
                "element vertex",
                format!(
                    "a {what} needs all of {}; missing: {}",
                    names.join(" "),
                    missing.join(" ")
                ),
            ))
        }
    }
}

/// The vertex properties `x y z`, which every PLY file streak reads must have.
fn position_properties(vertices: &ElementDecl, path: &Path) -> Result<[usize; 3]> {
    let group = find_group(vertices, ["x", "y", "z"], "position", path)?.ok_or_else(|| {
        Error::input(
            path,
            "element vertex",
            "no position: the vertex element needs properties x, y and z",
        )
    })?;
    Ok(group.map(|(index, _)| index))
}

/// Collects validated vertices into a [`PointCloud`].
struct CloudBuilder {
    cloud: PointCloud,
}

impl CloudBuilder {
    fn new(layout: &VertexLayout, capacity: usize) -> Self {
        CloudBuilder {
            cloud: PointCloud {
                positions: Vec::with_capacity(capacity),
                normals: layout.normal.map(|_| Vec::with_capacity(capacity)),
                colors: layout.color.map(|_| Vec::with_capacity(capacity)),
                radii: layout.radius.map(|_| Vec::with_capacity(capacity)),
            },
        }
    }

    fn push(
        &mut self,
        layout: &VertexLayout,
        vertices: &ElementDecl,
        index: usize,
        values: &[f64],
        path: &Path,
    ) -> Result<()> {
        let finite = |property: usize| -> Result<f64> {
            let value = values[property];
            if value.is_finite() {
                Ok(value)
            } else {
                Err(Error::input(
                    path,
                    format!(
                        "vertex {index} property {}",
                        vertices.properties[property].name
                    ),
                    format!("value is {value}; every value must be a finite number"),
                ))
            }
        };
        let vector = |[x, y, z]: [usize; 3]| -> Result<DVec3> {
            Ok(DVec3::new(finite(x)?, finite(y)?, finite(z)?))
        };

        self.cloud.positions.push(vector(layout.position)?);
        if let (Some(indices), Some(normals)) = (layout.normal, &mut self.cloud.normals) {
            let normal = vector(indices)?;
            // Dividing by the largest component first keeps tiny but valid normals from
            // underflowing when squared.
            let largest = normal.abs().max_element();
            if largest == 0.0 {
                return Err(Error::input(
                    path,
                    format!("vertex {index}"),
                    "normal has zero length; give a unit normal or leave normals out to have \
                     them estimated",
                ));
            }
            normals.push((normal / largest).normalize());
        }
        if let (Some(channels), Some(colors)) = (layout.color, &mut self.cloud.colors) {
            let mut rgb = [0.0f32; 3];
            for (out, (property, encoding)) in rgb.iter_mut().zip(channels) {
                let value = finite(property)?;
                *out = match encoding {
                    ColorEncoding::Srgb8 => srgb_to_linear(value / 255.0),
                    ColorEncoding::Linear if (0.0..=1.0).contains(&value) => value as f32,
                    ColorEncoding::Linear => {
                        return Err(Error::input(
                            path,
                            format!(
                                "vertex {index} property {}",
                                vertices.properties[property].name
                            ),
                            format!(
                                "float colour {value} is outside [0, 1]; store 0–255 colours \
                                 as uchar"
                            ),
                        ))
                    }
                };
            }
            colors.push(rgb);
        }
        if let (Some(property), Some(radii)) = (layout.radius, &mut self.cloud.radii) {
            let radius = finite(property)?;
            if radius <= 0.0 {
                return Err(Error::input(
                    path,
                    format!("vertex {index} property radius"),
                    format!("radius {radius} must be positive"),
                ));
            }
            radii.push(radius);
        }
        Ok(())
    }

    fn finish(self) -> PointCloud {
        self.cloud
    }
}

/// Where a body reader puts one record's values.
struct Record {
    /// One per property; a list leaves its slot untouched.
    values: Vec<f64>,
    /// The list property whose items are kept, if any.
    keep: Option<usize>,
    /// The kept list's items.
    list: Vec<f64>,
}

impl Record {
    fn new(element: &ElementDecl, keep: Option<usize>) -> Self {
        Record {
            values: vec![0.0; element.properties.len()],
            keep,
            list: Vec::new(),
        }
    }
}

/// Walks the data after the header one element record at a time.
enum BodyReader<'a> {
    Ascii(AsciiBody<'a>),
    Binary(BinaryBody<'a>),
}

impl<'a> BodyReader<'a> {
    /// A reader of the data after `header` in `bytes`.
    fn new(header: &Header, bytes: &'a [u8]) -> Self {
        let body = &bytes[header.body_offset..];
        match header.encoding {
            Encoding::Ascii => BodyReader::Ascii(AsciiBody::new(body, header.body_first_line)),
            Encoding::BinaryLittleEndian => BodyReader::Binary(BinaryBody::new(body, false)),
            Encoding::BinaryBigEndian => BodyReader::Binary(BinaryBody::new(body, true)),
        }
    }

    /// How many records of `element` to allocate for: never trust the declared count, the data
    /// left bounds how many records fit.
    fn capacity(&self, element: &ElementDecl) -> usize {
        let left = match self {
            BodyReader::Ascii(body) => body.rest.len(),
            BodyReader::Binary(body) => body.bytes.len() - body.position,
        };
        element.count.min(left / self.min_record_bytes(element))
    }

    /// A lower bound on the bytes one record of `element` takes, at least 1.
    fn min_record_bytes(&self, element: &ElementDecl) -> usize {
        let bytes = match self {
            // Each value needs a digit and a separator.
            BodyReader::Ascii(_) => 2 * element.properties.len(),
            BodyReader::Binary(_) => element
                .properties
                .iter()
                .map(|property| match property.ty {
                    PropertyType::Scalar(ty) => ty.size(),
                    PropertyType::List { count, .. } => count.size(),
                })
                .sum(),
        };
        bytes.max(1)
    }

    fn skip_element(&mut self, element: &ElementDecl, path: &Path) -> Result<()> {
        // An element without properties occupies no data, however large its count.
        if element.properties.is_empty() {
            return Ok(());
        }
        let mut ignored = Record::new(element, None);
        for index in 0..element.count {
            let complete = match self {
                // Ascii records are lines: no need to look inside what is ignored anyway.
                BodyReader::Ascii(body) => body.next_line().is_some(),
                BodyReader::Binary(body) => body.read_record(element, index, &mut ignored, path)?,
            };
            if !complete {
                return Err(Error::input(
                    path,
                    format!("element {}", element.name),
                    format!(
                        "the header declares {} {} records but the data ends after {index}",
                        element.count, element.name
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Reads record `index` of `element` into `record`. Returns false when the data ends before
    /// the record starts.
    fn read_record(
        &mut self,
        element: &ElementDecl,
        index: usize,
        record: &mut Record,
        path: &Path,
    ) -> Result<bool> {
        record.list.clear();
        match self {
            BodyReader::Ascii(body) => body.read_record(element, index, record, path),
            BodyReader::Binary(body) => body.read_record(element, index, record, path),
        }
    }
}

fn record_field(element: &ElementDecl, index: usize, property: &PropertyDecl) -> String {
    format!("{} {index} property {}", element.name, property.name)
}

/// Ascii PLY data: one record per line, values separated by whitespace.
struct AsciiBody<'a> {
    rest: &'a [u8],
    line_number: usize,
}

impl<'a> AsciiBody<'a> {
    fn new(body: &'a [u8], first_line: usize) -> Self {
        AsciiBody {
            rest: body,
            line_number: first_line - 1,
        }
    }

    /// The next line that is not blank, or `None` at the end of the data.
    fn next_line(&mut self) -> Option<&'a [u8]> {
        while !self.rest.is_empty() {
            let end = self
                .rest
                .iter()
                .position(|&b| b == b'\n')
                .unwrap_or(self.rest.len());
            let line = &self.rest[..end];
            self.rest = &self.rest[(end + 1).min(self.rest.len())..];
            self.line_number += 1;
            if !line.iter().all(u8::is_ascii_whitespace) {
                return Some(line);
            }
        }
        None
    }

    fn read_record(
        &mut self,
        element: &ElementDecl,
        index: usize,
        record: &mut Record,
        path: &Path,
    ) -> Result<bool> {
        let Some(line) = self.next_line() else {
            return Ok(false);
        };
        let line_number = self.line_number;
        let mut tokens = line
            .split(u8::is_ascii_whitespace)
            .filter(|token| !token.is_empty());
        let mut next_value = |property: &PropertyDecl, ty: ScalarType| -> Result<f64> {
            let field = || record_field(element, index, property);
            let token = tokens.next().ok_or_else(|| {
                Error::input(
                    path,
                    field(),
                    format!("line {line_number} ends before this value"),
                )
            })?;
            parse_ascii_value(token, ty).ok_or_else(|| {
                Error::input(
                    path,
                    field(),
                    format!(
                        "`{}` on line {line_number} is not a valid {}",
                        String::from_utf8_lossy(token),
                        ty.name()
                    ),
                )
            })
        };
        for (slot, property) in element.properties.iter().enumerate() {
            match property.ty {
                PropertyType::Scalar(ty) => record.values[slot] = next_value(property, ty)?,
                PropertyType::List { count, item } => {
                    let length = next_value(property, count)?;
                    if length < 0.0 {
                        return Err(Error::input(
                            path,
                            record_field(element, index, property),
                            format!("list length {length} on line {line_number} is negative"),
                        ));
                    }
                    let keep = record.keep == Some(slot);
                    for _ in 0..length as u64 {
                        let value = next_value(property, item)?;
                        if keep {
                            record.list.push(value);
                        }
                    }
                }
            }
        }
        if tokens.next().is_some() {
            return Err(Error::input(
                path,
                format!("{} {index}", element.name),
                format!(
                    "line {line_number} has more values than the {} properties the header \
                     declares",
                    element.properties.len()
                ),
            ));
        }
        Ok(true)
    }
}

/// Parses one ascii token as a value of type `ty`: integers must be whole and in range; floats are
/// rounded to the declared precision, so ascii and binary files of the same data agree.
fn parse_ascii_value(token: &[u8], ty: ScalarType) -> Option<f64> {
    let text = std::str::from_utf8(token).ok()?;
    match ty.integer_range() {
        Some((min, max)) => {
            let value = text.parse::<i64>().ok()?;
            (min..=max).contains(&value).then_some(value as f64)
        }
        None if ty == ScalarType::Float32 => text.parse::<f32>().ok().map(f64::from),
        None => text.parse::<f64>().ok(),
    }
}

fn truncated(element: &ElementDecl, index: usize, property: &PropertyDecl, path: &Path) -> Error {
    Error::input(
        path,
        record_field(element, index, property),
        format!(
            "the data ends in the middle of this record (truncated file?); the header declares \
             {} {} records",
            element.count, element.name
        ),
    )
}

/// Binary PLY data in either byte order.
struct BinaryBody<'a> {
    bytes: &'a [u8],
    position: usize,
    big_endian: bool,
}

impl<'a> BinaryBody<'a> {
    fn new(bytes: &'a [u8], big_endian: bool) -> Self {
        BinaryBody {
            bytes,
            position: 0,
            big_endian,
        }
    }

    fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let bytes: [u8; N] = self
            .bytes
            .get(self.position..self.position + N)?
            .try_into()
            .ok()?;
        self.position += N;
        Some(if self.big_endian {
            bytes
        } else {
            let mut reversed = bytes;
            reversed.reverse();
            reversed
        })
    }

    /// Reads one value, or `None` when the data ends first.
    fn read_value(&mut self, ty: ScalarType) -> Option<f64> {
        // `take` returns big-endian bytes whatever the file's byte order.
        Some(match ty {
            ScalarType::Int8 => i8::from_be_bytes(self.take()?).into(),
            ScalarType::UInt8 => u8::from_be_bytes(self.take()?).into(),
            ScalarType::Int16 => i16::from_be_bytes(self.take()?).into(),
            ScalarType::UInt16 => u16::from_be_bytes(self.take()?).into(),
            ScalarType::Int32 => i32::from_be_bytes(self.take()?).into(),
            ScalarType::UInt32 => u32::from_be_bytes(self.take()?).into(),
            ScalarType::Float32 => f32::from_be_bytes(self.take()?).into(),
            ScalarType::Float64 => f64::from_be_bytes(self.take()?),
        })
    }

    fn read_record(
        &mut self,
        element: &ElementDecl,
        index: usize,
        record: &mut Record,
        path: &Path,
    ) -> Result<bool> {
        if self.position >= self.bytes.len() {
            return Ok(false);
        }
        for (slot, property) in element.properties.iter().enumerate() {
            match property.ty {
                PropertyType::Scalar(ty) => {
                    record.values[slot] = self
                        .read_value(ty)
                        .ok_or_else(|| truncated(element, index, property, path))?;
                }
                PropertyType::List { count, item } => {
                    let start = self.position;
                    self.skip_list(element, index, property, count, item, path)?;
                    if record.keep == Some(slot) {
                        // The list is known to be complete: go back and read its items.
                        let items = (self.position - start - count.size()) / item.size();
                        self.position = start + count.size();
                        record
                            .list
                            .extend((0..items).filter_map(|_| self.read_value(item)));
                    }
                }
            }
        }
        Ok(true)
    }

    /// Moves past a list, checking that all of it is there.
    fn skip_list(
        &mut self,
        element: &ElementDecl,
        index: usize,
        property: &PropertyDecl,
        count: ScalarType,
        item: ScalarType,
        path: &Path,
    ) -> Result<()> {
        let length = self
            .read_value(count)
            .ok_or_else(|| truncated(element, index, property, path))?;
        if length < 0.0 {
            return Err(Error::input(
                path,
                record_field(element, index, property),
                format!("list length {length} is negative"),
            ));
        }
        let end = (length as usize)
            .checked_mul(item.size())
            .and_then(|bytes| self.position.checked_add(bytes))
            .filter(|&end| end <= self.bytes.len())
            .ok_or_else(|| truncated(element, index, property, path))?;
        self.position = end;
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// PLY writing
// ---------------------------------------------------------------------------------------------

/// Write a cloud as PLY, ascii or binary little endian. Positions, normals and radii are written
/// as double and colours as linear float, so reading the file back gives the same cloud exactly.
/// Fails with `InvalidInput` when an attribute's length differs from the number of positions.
pub fn write_ply(cloud: &PointCloud, binary: bool, out: &mut impl Write) -> std::io::Result<()> {
    let count = cloud.positions.len();
    let lengths_match = cloud.normals.as_ref().is_none_or(|v| v.len() == count)
        && cloud.colors.as_ref().is_none_or(|v| v.len() == count)
        && cloud.radii.as_ref().is_none_or(|v| v.len() == count);
    if !lengths_match {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "point cloud attributes must have one entry per position",
        ));
    }

    let mut out = std::io::BufWriter::new(out);
    let format = if binary {
        "binary_little_endian"
    } else {
        "ascii"
    };
    writeln!(out, "ply\nformat {format} 1.0\ncomment written by streak")?;
    writeln!(out, "element vertex {count}")?;
    let mut properties = vec![("double", "x"), ("double", "y"), ("double", "z")];
    if cloud.normals.is_some() {
        properties.extend([("double", "nx"), ("double", "ny"), ("double", "nz")]);
    }
    if cloud.colors.is_some() {
        properties.extend([("float", "red"), ("float", "green"), ("float", "blue")]);
    }
    if cloud.radii.is_some() {
        properties.push(("double", "radius"));
    }
    for (ty, name) in properties {
        writeln!(out, "property {ty} {name}")?;
    }
    writeln!(out, "end_header")?;

    for index in 0..count {
        let mut doubles = cloud.positions[index].to_array().to_vec();
        if let Some(normals) = &cloud.normals {
            doubles.extend(normals[index].to_array());
        }
        let color = cloud.colors.as_ref().map(|colors| colors[index]);
        let radius = cloud.radii.as_ref().map(|radii| radii[index]);
        if binary {
            for value in &doubles {
                out.write_all(&value.to_le_bytes())?;
            }
            for channel in color.into_iter().flatten() {
                out.write_all(&channel.to_le_bytes())?;
            }
            if let Some(value) = radius {
                out.write_all(&value.to_le_bytes())?;
            }
        } else {
            // Rust prints floats with the fewest digits that read back to the same value.
            let mut words: Vec<String> = doubles.iter().map(f64::to_string).collect();
            words.extend(
                color
                    .into_iter()
                    .flatten()
                    .map(|channel| channel.to_string()),
            );
            words.extend(radius.map(|value| value.to_string()));
            writeln!(out, "{}", words.join(" "))?;
        }
    }
    out.flush()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    const BAD: &str = "bad.ply";

    /// A value as the test PLY encoder writes it.
    #[derive(Clone, Debug)]
    enum Value {
        Float(f32),
        UChar(u8),
        Int(i32),
        /// A list with uchar count and int items.
        List(Vec<i32>),
    }

    /// Encodes `header` (element and property lines) and `records` in the given PLY format.
    fn encode_ply(format: &str, header: &str, records: &[Vec<Value>]) -> Vec<u8> {
        let mut bytes =
            format!("ply\nformat {format} 1.0\ncomment test data\n{header}end_header\n")
                .into_bytes();
        let big_endian = format == "binary_big_endian";
        for record in records {
            if format == "ascii" {
                let words: Vec<String> = record
                    .iter()
                    .map(|value| match value {
                        Value::Float(v) => v.to_string(),
                        Value::UChar(v) => v.to_string(),
                        Value::Int(v) => v.to_string(),
                        Value::List(items) => std::iter::once(items.len().to_string())
                            .chain(items.iter().map(i32::to_string))
                            .collect::<Vec<_>>()
                            .join(" "),
                    })
                    .collect();
                bytes.extend(format!("{}\n", words.join(" ")).into_bytes());
                continue;
            }
            let mut push = |be: &[u8], le: &[u8]| bytes.extend(if big_endian { be } else { le });
            for value in record {
                match value {
                    Value::Float(v) => push(&v.to_be_bytes(), &v.to_le_bytes()),
                    Value::UChar(v) => push(&[*v], &[*v]),
                    Value::Int(v) => push(&v.to_be_bytes(), &v.to_le_bytes()),
                    Value::List(items) => {
                        push(&[items.len() as u8], &[items.len() as u8]);
                        for item in items {
                            push(&item.to_be_bytes(), &item.to_le_bytes());
                        }
                    }
                }
            }
        }
        bytes
    }

    const CAMERA: &str = "element camera 1\nproperty float view_x\nproperty list uchar int tags\n";
    const VERTICES: &str = "element vertex 3\n\
        property float x\nproperty float y\nproperty float z\n\
        property float nx\nproperty float ny\nproperty float nz\n\
        property uchar red\nproperty uchar green\nproperty uchar blue\n\
        property float radius\nproperty int flags\n";
    const FACE: &str = "element face 1\nproperty list uchar int vertex_indices\n";
    /// Bytes of one binary vertex record: six floats, three uchars, a float and an int.
    const VERTEX_BYTES: usize = 6 * 4 + 3 + 4 + 4;
    /// Bytes of the binary face record: a uchar count and three ints.
    const FACE_BYTES: usize = 1 + 3 * 4;

    fn full_header() -> String {
        format!("{CAMERA}{VERTICES}{FACE}")
    }

    fn vertex(position: [f32; 3], normal: [f32; 3], rgb: [u8; 3], radius: f32) -> Vec<Value> {
        let flags = Value::Int(-4);
        let floats = position.into_iter().chain(normal).map(Value::Float);
        let colours = rgb.map(Value::UChar);
        floats
            .chain(colours)
            .chain([Value::Float(radius), flags])
            .collect()
    }

    fn full_records() -> Vec<Vec<Value>> {
        vec![
            vec![Value::Float(2.5), Value::List(vec![7, -8])],
            vertex([0.001, -1.25, 3.0e6], [0.0, 0.0, 2.0], [0, 128, 255], 0.125),
            vertex([-7.5, 0.1, 1.0 / 3.0], [3.0, -4.0, 0.0], [255, 1, 64], 2.0),
            vertex([1e-30, 123.456, -0.0], [0.6, 0.0, 0.8], [10, 20, 30], 1e-3),
            vec![Value::List(vec![0, 1, 2])],
        ]
    }

    fn parse(bytes: &[u8]) -> Result<PointCloud> {
        parse_ply(bytes, Path::new(BAD))
    }

    /// The error of `result`, which must name the file and `field`; returns the message.
    fn error_naming<T: std::fmt::Debug>(result: Result<T>, field: &str) -> String {
        let message = match result {
            Ok(value) => panic!("expected an error at {field}, got {value:?}"),
            Err(error) => error.to_string(),
        };
        assert!(
            message.starts_with(&format!("{BAD}: {field}: ")),
            "`{message}` should name {BAD} and {field}"
        );
        message
    }

    /// Parses `bytes`, expecting an error that names the file and `field`; returns the message.
    fn expect_error(bytes: &[u8], field: &str) -> String {
        error_naming(parse(bytes).map(|cloud| cloud.positions.len()), field)
    }

    #[test]
    fn ascii_and_binary_encodings_read_alike() {
        let records = full_records();
        let ascii = parse(&encode_ply("ascii", &full_header(), &records)).unwrap();
        let little = parse(&encode_ply(
            "binary_little_endian",
            &full_header(),
            &records,
        ))
        .unwrap();
        let big = parse(&encode_ply("binary_big_endian", &full_header(), &records)).unwrap();
        let crlf = String::from_utf8(encode_ply("ascii", &full_header(), &records))
            .unwrap()
            .replace('\n', "\r\n");
        assert_eq!(ascii, little);
        assert_eq!(ascii, big);
        assert_eq!(ascii, parse(crlf.as_bytes()).unwrap());

        assert_eq!(
            ascii.positions[0],
            DVec3::new(0.001f32.into(), -1.25, 3.0e6)
        );
        assert_eq!(ascii.positions[1].y, f64::from(0.1f32));
        let normals = ascii.normals.as_ref().unwrap();
        assert_eq!(normals[0], DVec3::Z);
        assert!((normals[1] - DVec3::new(0.6, -0.8, 0.0)).length() < 1e-15);
        let colors = ascii.colors.as_ref().unwrap();
        assert_eq!(colors[0][0], 0.0);
        assert!(
            (colors[0][1] - 0.215_861).abs() < 1e-5,
            "sRGB 128 decodes to 0.2159"
        );
        assert_eq!(colors[0][2], 1.0);
        assert_eq!(ascii.radii, Some(vec![0.125, 2.0, f64::from(1e-3f32)]));
    }

    #[test]
    fn write_ply_round_trips_exactly() {
        let full = PointCloud {
            positions: vec![
                DVec3::new(0.1, -1.0 / 3.0, 1e-300),
                DVec3::new(2e15, 0.0, -7.25),
            ],
            normals: Some(vec![DVec3::new(0.6, 0.0, 0.8), DVec3::new(0.0, -1.0, 0.0)]),
            colors: Some(vec![[0.0, 0.5, 1.0], [0.123_456_79, 0.9, 0.01]]),
            radii: Some(vec![0.3, 1.0 / 7.0]),
        };
        let bare = PointCloud {
            positions: full.positions.clone(),
            ..PointCloud::default()
        };
        for cloud in [full, bare] {
            for binary in [false, true] {
                let mut bytes = Vec::new();
                write_ply(&cloud, binary, &mut bytes).unwrap();
                assert_eq!(parse(&bytes).unwrap(), cloud, "binary: {binary}");
            }
        }
    }

    #[test]
    fn write_ply_rejects_mismatched_attributes() {
        let cloud = PointCloud {
            positions: vec![DVec3::ZERO; 2],
            radii: Some(vec![1.0]),
            ..PointCloud::default()
        };
        let error = write_ply(&cloud, true, &mut Vec::new()).unwrap_err();
        assert_eq!(error.kind(), std::io::ErrorKind::InvalidInput);
    }

    #[test]
    fn read_ply_gunzips_gz_files() {
        use flate2::{write::GzEncoder, Compression};
        let bytes = encode_ply("binary_big_endian", &full_header(), &full_records());
        let path = std::env::temp_dir().join(format!("streak-test-{}.ply.gz", std::process::id()));
        let mut encoder = GzEncoder::new(Vec::new(), Compression::fast());
        encoder.write_all(&bytes).unwrap();
        std::fs::write(&path, encoder.finish().unwrap()).unwrap();
        let from_gz = read_ply(&path);
        std::fs::remove_file(&path).unwrap();
        assert_eq!(from_gz.unwrap(), parse(&bytes).unwrap());

        let missing = read_ply(Path::new("/nonexistent/cloud.ply")).unwrap_err();
        assert!(matches!(missing, Error::Io { .. }));
    }

    fn test_data(name: &str) -> PathBuf {
        Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data")).join(name)
    }

    #[test]
    fn reads_ascii_range_scan_with_trailing_list_element() {
        let cloud = read_ply(&test_data("bunny_range_scan_bun000.ply.gz")).unwrap();
        assert_eq!(cloud.positions.len(), 40_256);
        assert!(cloud.normals.is_none() && cloud.colors.is_none() && cloud.radii.is_none());
        let first = [-0.06325f32, 0.0359793, 0.0420873].map(f64::from);
        assert_eq!(cloud.positions[0], DVec3::from_array(first));
    }

    #[test]
    fn reads_binary_mesh_except_for_its_one_zero_normal() {
        let path = test_data("dragon_100k.ply.gz");
        // The file stores a zero normal for vertex 9121 (a vertex of degenerate faces only).
        let message = read_ply(&path).unwrap_err().to_string();
        assert!(
            message.contains("vertex 9121: normal has zero length"),
            "{message}"
        );

        // With that one normal repaired in memory, every vertex loads, faces skipped.
        let mut bytes = read_file(&path, MAX_PLY_BYTES).unwrap();
        let header_end = b"end_header\n";
        let body = header_end.len()
            + bytes
                .windows(header_end.len())
                .position(|w| w == header_end)
                .unwrap();
        let nz = body + 9121 * 24 + 20;
        assert_eq!(bytes[nz - 8..nz + 4], [0; 12]);
        bytes[nz..nz + 4].copy_from_slice(&1.0f32.to_le_bytes());
        let cloud = parse_ply(&bytes, &path).unwrap();
        assert_eq!(cloud.positions.len(), 50_002);
        let normals = cloud.normals.unwrap();
        assert_eq!(normals.len(), 50_002);
        assert!(normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-12));
    }

    const XYZ: &str = "element vertex 2\nproperty float x\nproperty float y\nproperty float z\n";
    const YZ: &str = "property float y\nproperty float z\n";

    fn ascii(header: &str, body: &str) -> Vec<u8> {
        format!("ply\nformat ascii 1.0\n{header}end_header\n{body}").into_bytes()
    }

    #[test]
    fn malformed_headers_are_errors() {
        expect_error(b"", "header line 1");
        expect_error(b"solid cube\nfacet normal 0 0 1\n", "header line 1");
        let message = expect_error(b"\x1f\x8b\x08\x00", "header line 1");
        assert!(message.contains("gzip"));
        let message = expect_error(b"ply\nformat binary_middle_endian 1.0\n", "header line 2");
        assert!(message.contains("binary_middle_endian"));
        expect_error(b"ply\nformat ascii 1.0\nelement vertex 1\n", "header");
        expect_error(
            b"ply\nelement vertex 1\nproperty float x\nend_header\n",
            "header",
        );
        expect_error(&ascii("element vertex -3\n", ""), "header line 3");
        expect_error(&ascii("element vertex many\n", ""), "header line 3");
        expect_error(&ascii("property float x\n", ""), "header line 3");
        expect_error(
            &ascii("element vertex 1\nproperty float128 x\n", ""),
            "header line 4",
        );
        expect_error(
            &ascii("element vertex 1\nproperty list float int x\n", ""),
            "header line 4",
        );
        expect_error(
            &ascii("element vertex 1\nelement vertex 1\n", ""),
            "header line 4",
        );
        expect_error(
            &ascii("element face 1\nproperty uchar n\n", "1\n"),
            "element vertex",
        );
    }

    #[test]
    fn missing_or_mistyped_properties_are_errors() {
        let message = expect_error(
            &ascii(&format!("element vertex 1\n{YZ}"), "1 2\n"),
            "element vertex",
        );
        assert!(message.ends_with("missing: x"), "{message}");
        let message = expect_error(
            &ascii(&format!("{XYZ}property float nx\n"), ""),
            "element vertex",
        );
        assert!(message.ends_with("missing: ny nz"), "{message}");
        let message = expect_error(
            &ascii(
                &format!("element vertex 1\nproperty list uchar float x\n{YZ}"),
                "",
            ),
            "element vertex",
        );
        assert!(message.contains("list"));
        let colours = "property int red\nproperty int green\nproperty int blue\n";
        let message = expect_error(&ascii(&format!("{XYZ}{colours}"), ""), "element vertex");
        assert!(message.contains("uchar"));
        let no_vertices = XYZ.replace("vertex 2", "vertex 0");
        expect_error(&ascii(&no_vertices, ""), "element vertex");
    }

    #[test]
    fn bad_values_are_errors_naming_vertex_and_property() {
        let message = expect_error(&ascii(XYZ, "1 2 3\nnan 2 3\n"), "vertex 1 property x");
        assert!(message.contains("NaN"));
        expect_error(&ascii(XYZ, "1 2 3\n4 five 6\n"), "vertex 1 property y");
        expect_error(&ascii(XYZ, "1 2 3\n4 1e39 6\n"), "vertex 1 property y");
        expect_error(&ascii(XYZ, "1 2\n4 5 6\n"), "vertex 0 property z");
        expect_error(&ascii(XYZ, "1 2 3 4\n4 5 6\n"), "vertex 0");

        let inf_header =
            "element vertex 2\nproperty float x\nproperty double y\nproperty float z\n";
        let mut binary = b"ply\nformat binary_little_endian 1.0\n".to_vec();
        binary.extend(format!("{inf_header}end_header\n").bytes());
        binary.extend(1.0f32.to_le_bytes());
        binary.extend(f64::INFINITY.to_le_bytes());
        binary.extend(3.0f32.to_le_bytes());
        expect_error(&binary, "vertex 0 property y");

        let normals = "property float nx\nproperty float ny\nproperty float nz\n";
        let message = expect_error(
            &ascii(&format!("{XYZ}{normals}"), "0 0 0 0 0 1\n1 1 1 0 0 0\n"),
            "vertex 1",
        );
        assert!(message.contains("normal has zero length"), "{message}");

        let colours = "property uchar red\nproperty uchar green\nproperty uchar blue\n";
        expect_error(
            &ascii(&format!("{XYZ}{colours}"), "0 0 0 1 2 3\n0 0 0 1 256 3\n"),
            "vertex 1 property green",
        );
        let float_colours = "property float red\nproperty float green\nproperty float blue\n";
        expect_error(
            &ascii(&format!("{XYZ}{float_colours}"), "0 0 0 0 0.5 255\n"),
            "vertex 0 property blue",
        );
        expect_error(
            &ascii(
                &format!("{XYZ}property float radius\n"),
                "0 0 0 1\n0 0 0 -1\n",
            ),
            "vertex 1 property radius",
        );
    }

    #[test]
    fn short_data_is_an_error() {
        let message = expect_error(&ascii(XYZ, "1 2 3\n"), "element vertex");
        assert!(message.contains("declares 2 vertices"), "{message}");

        let bytes = encode_ply("binary_little_endian", &full_header(), &full_records());
        let vertex_start = bytes.len() - FACE_BYTES - 3 * VERTEX_BYTES;
        expect_error(&bytes[..vertex_start + VERTEX_BYTES], "element vertex");
        expect_error(
            &bytes[..vertex_start + VERTEX_BYTES + 5],
            "vertex 1 property y",
        );
        expect_error(&bytes[..vertex_start - 2], "camera 0 property tags");

        let huge = format!("element vertex 1000000000000000000\nproperty float x\n{YZ}");
        expect_error(&ascii(&huge, "1 2 3\n"), "element vertex");
        let mut binary =
            format!("ply\nformat binary_big_endian 1.0\n{huge}end_header\n").into_bytes();
        binary.extend([0u8; 24]);
        expect_error(&binary, "element vertex");
        let huge_skipped = "element thing 1000000000000000000\nproperty uchar a\n";
        expect_error(
            &ascii(&format!("{huge_skipped}{XYZ}"), "1\n2\n"),
            "element thing",
        );
    }

    #[test]
    fn damaged_files_never_panic() {
        // Faces before the vertices, so that every byte matters.
        let header = format!("{CAMERA}{FACE}{VERTICES}");
        let mut records = full_records();
        records[1..].rotate_right(1);
        for format in ["ascii", "binary_little_endian", "binary_big_endian"] {
            let bytes = encode_ply(format, &header, &records);
            assert_eq!(parse(&bytes).unwrap().positions.len(), 3);
            for end in 0..bytes.len() - 1 {
                assert!(parse(&bytes[..end]).is_err(), "{format} cut at {end}");
            }
            for index in 0..bytes.len() {
                for flip in [0x01, 0x80, 0xff] {
                    let mut damaged = bytes.clone();
                    damaged[index] ^= flip;
                    let _ = parse(&damaged);
                }
            }
        }
    }

    fn parse_mesh(bytes: &[u8]) -> Result<Mesh> {
        parse_ply_mesh(bytes, Path::new(BAD))
    }

    /// Parses `bytes` as a mesh, expecting an error that names the file and `field`.
    fn expect_mesh_error(bytes: &[u8], field: &str) -> String {
        error_naming(parse_mesh(bytes), field)
    }

    #[test]
    fn a_mesh_of_more_vertices_or_faces_than_streak_reads_is_refused_from_its_header() {
        use crate::surfels::mesh::{MAX_MESH_TRIANGLES, MAX_MESH_VERTICES};
        // A few bytes of header may declare any count; each face is at least one triangle.
        for (element, count, what) in [
            ("vertex", MAX_MESH_VERTICES + 1, "vertices"),
            ("face", MAX_MESH_TRIANGLES + 1, "triangles"),
        ] {
            let text = format!(
                "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
                 property float z\nelement face {}\nproperty list uchar int vertex_indices\n\
                 end_header\n",
                if element == "vertex" { count } else { 3 },
                if element == "face" { count } else { 1 },
            );
            let message = expect_mesh_error(text.as_bytes(), &format!("element {element}"));
            assert!(
                message.contains(&format!("more than 33554432 {what}")),
                "{message}"
            );
        }
    }

    #[test]
    fn mesh_faces_read_alike_in_every_encoding() {
        // The full file has a camera list before the vertices and a zero-length normal a mesh
        // does not need.
        let mut records = full_records();
        records[1] = vertex([0.0, 0.0, 0.0], [0.0; 3], [0, 0, 0], 1.0);
        records.push(vec![Value::List(vec![2, 1, 0])]);
        let header = full_header().replace("face 1", "face 2");
        let ascii = parse_mesh(&encode_ply("ascii", &header, &records)).unwrap();
        for format in ["binary_little_endian", "binary_big_endian"] {
            assert_eq!(
                parse_mesh(&encode_ply(format, &header, &records)).unwrap(),
                ascii
            );
        }
        assert_eq!(ascii.triangles, vec![[0, 1, 2], [2, 1, 0]]);
        assert_eq!(ascii.positions.len(), 3);
        assert_eq!(
            ascii.positions[1],
            DVec3::new(-7.5, 0.1f32.into(), (1.0f32 / 3.0).into())
        );

        // Faces before the vertices, a polygon, and `list int uint vertex_index` in binary.
        let mut binary = b"ply\nformat binary_little_endian 1.0\n\
            element face 2\nproperty list int uint vertex_index\nproperty uchar flags\n\
            element vertex 5\nproperty double x\nproperty double y\nproperty double z\n\
            end_header\n"
            .to_vec();
        for face in [&[0u32, 1, 2, 3, 4][..], &[4, 3, 2]] {
            binary.extend((face.len() as i32).to_le_bytes());
            for index in face {
                binary.extend(index.to_le_bytes());
            }
            binary.push(7);
        }
        for k in 0..5 {
            for value in [f64::from(k), -f64::from(k), 0.5] {
                binary.extend(value.to_le_bytes());
            }
        }
        let mesh = parse_mesh(&binary).unwrap();
        assert_eq!(
            mesh.triangles,
            vec![[0, 1, 2], [0, 2, 3], [0, 3, 4], [4, 3, 2]]
        );
        assert_eq!(mesh.positions[4], DVec3::new(4.0, -4.0, 0.5));
    }

    #[test]
    fn bad_faces_are_errors_naming_face_and_property() {
        let header = "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
            element face 1\nproperty list uchar int vertex_indices\n";
        let points = "0 0 0\n1 0 0\n0 1 0\n";
        let with_face = |face: &str| ascii(header, &format!("{points}{face}\n"));
        let message = expect_mesh_error(&with_face("3 0 1 3"), "face 0 property vertex_indices");
        assert!(message.contains("index 3 is out of range"), "{message}");
        expect_mesh_error(&with_face("3 0 -1 2"), "face 0 property vertex_indices");
        let message = expect_mesh_error(&with_face("2 0 1"), "face 0 property vertex_indices");
        assert!(message.contains("at least 3"), "{message}");
        expect_mesh_error(&with_face("3 0 1"), "face 0 property vertex_indices");
        expect_mesh_error(&with_face("3 0 1 1.5"), "face 0 property vertex_indices");
        expect_mesh_error(&ascii(header, points), "element face");
        expect_mesh_error(
            &ascii(&XYZ.replace("vertex 2", "vertex 3"), points),
            "element face",
        );
        let float_list = header.replace("uchar int", "uchar float");
        let message = expect_mesh_error(&ascii(&float_list, points), "element face");
        assert!(message.contains("integers"), "{message}");
        let no_list = header.replace("list uchar int vertex_indices", "int vertex_indices");
        expect_mesh_error(&ascii(&no_list, points), "element face");
        let unnamed = header.replace("vertex_indices", "corners");
        expect_mesh_error(&ascii(&unnamed, points), "element face");

        // Binary data cut inside the face list.
        let records = vec![
            vec![Value::Float(0.0), Value::Float(0.0), Value::Float(0.0)],
            vec![Value::Float(1.0), Value::Float(0.0), Value::Float(0.0)],
            vec![Value::Float(0.0), Value::Float(1.0), Value::Float(0.0)],
            vec![Value::List(vec![0, 1, 2])],
        ];
        let bytes = encode_ply("binary_little_endian", header, &records);
        assert_eq!(parse_mesh(&bytes).unwrap().triangles, vec![[0, 1, 2]]);
        expect_mesh_error(&bytes[..bytes.len() - 2], "face 0 property vertex_indices");
        expect_mesh_error(&bytes[..bytes.len() - 13], "element face");
        for end in 0..bytes.len() - 1 {
            assert!(parse_mesh(&bytes[..end]).is_err(), "cut at {end}");
        }
        for index in 0..bytes.len() {
            let mut damaged = bytes.clone();
            damaged[index] ^= 0xff;
            let _ = parse_mesh(&damaged);
        }
    }
}
