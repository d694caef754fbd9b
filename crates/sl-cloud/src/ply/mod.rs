//! PLY (Stanford polygon file format) types shared by the reader and the writer.

pub(crate) mod header;
pub(crate) mod mesh;
pub(crate) mod read;
pub(crate) mod scalar;
pub(crate) mod write;

/// How the body of a PLY file is encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum PlyEncoding {
    /// Whitespace-separated decimal numbers, one element instance per line.
    Ascii,
    /// Packed binary, little-endian (what nearly every tool writes; the default).
    #[default]
    BinaryLittleEndian,
    /// Packed binary, big-endian.
    BinaryBigEndian,
}

impl PlyEncoding {
    /// The keyword used on the `format` line of the header.
    pub fn keyword(self) -> &'static str {
        match self {
            Self::Ascii => "ascii",
            Self::BinaryLittleEndian => "binary_little_endian",
            Self::BinaryBigEndian => "binary_big_endian",
        }
    }
}

/// Floating-point type used for positions and normals when writing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum PlyScalar {
    /// 32-bit `float`: half the size; about 0.06 µm resolution at 1 m in millimetre units,
    /// far below scanner noise, but the round trip of our `f64` positions is no longer exact.
    Float,
    /// 64-bit `double` (the default): our `f64` geometry survives a write/read round trip
    /// bit for bit, whatever the units or the distance from the origin.
    #[default]
    Double,
}

/// What [`write_ply`](crate::write_ply) writes: encoding and float width.
///
/// The default is binary little-endian with `double` positions and normals: lossless for our
/// `f64` geometry (see [`PlyScalar`]) and read by Open3D, MeshLab and CloudCompare. Colours are
/// always written as `uchar red/green/blue` and quality as `float quality`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct PlyFormat {
    /// Body encoding.
    pub encoding: PlyEncoding,
    /// Width of the `x y z nx ny nz` properties.
    pub scalar: PlyScalar,
}

/// A PLY scalar type (the aliases `int8`, `uint8`, ..., `float64` map to the same variants).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PlyScalarType {
    /// `char` / `int8`.
    Char,
    /// `uchar` / `uint8`.
    UChar,
    /// `short` / `int16`.
    Short,
    /// `ushort` / `uint16`.
    UShort,
    /// `int` / `int32`.
    Int,
    /// `uint` / `uint32`.
    UInt,
    /// `float` / `float32`.
    Float,
    /// `double` / `float64`.
    Double,
}

impl PlyScalarType {
    /// Size in bytes in a binary body.
    pub fn size(self) -> usize {
        match self {
            Self::Char | Self::UChar => 1,
            Self::Short | Self::UShort => 2,
            Self::Int | Self::UInt | Self::Float => 4,
            Self::Double => 8,
        }
    }

    /// The canonical (PLY 1.0) name: `char`, `uchar`, ..., `double`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Char => "char",
            Self::UChar => "uchar",
            Self::Short => "short",
            Self::UShort => "ushort",
            Self::Int => "int",
            Self::UInt => "uint",
            Self::Float => "float",
            Self::Double => "double",
        }
    }

    /// Parses a type name, canonical or sized alias (`uint8`, `float32`, ...).
    pub fn from_name(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Self::Char,
            "uchar" | "uint8" => Self::UChar,
            "short" | "int16" => Self::Short,
            "ushort" | "uint16" => Self::UShort,
            "int" | "int32" => Self::Int,
            "uint" | "uint32" => Self::UInt,
            "float" | "float32" => Self::Float,
            "double" | "float64" => Self::Double,
            _ => return None,
        })
    }

    /// Whether the type is `float` or `double`.
    pub fn is_float(self) -> bool {
        matches!(self, Self::Float | Self::Double)
    }
}

/// The type of one property of a PLY element.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PlyPropertyKind {
    /// One value per element instance.
    Scalar(PlyScalarType),
    /// A variable-length list: a count of type `count`, then that many values of type `item`
    /// (e.g. `property list uchar int vertex_indices` of faces).
    List {
        /// Type of the leading count.
        count: PlyScalarType,
        /// Type of the items.
        item: PlyScalarType,
    },
}

/// One `property` line of a PLY header.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct PlyProperty {
    /// Property name (`x`, `red`, `vertex_indices`...).
    pub name: String,
    /// Its type.
    pub kind: PlyPropertyKind,
}

/// One `element` of a PLY header with its properties.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct PlyElement {
    /// Element name (`vertex`, `face`, `range_grid`...).
    pub name: String,
    /// Number of instances declared by the header (not checked against the body).
    pub count: u64,
    /// Properties in file order.
    pub properties: Vec<PlyProperty>,
}

impl PlyElement {
    /// The property called `name`, if any.
    pub fn property(&self, name: &str) -> Option<&PlyProperty> {
        self.properties.iter().find(|p| p.name == name)
    }

    /// Size in bytes of one instance in a binary body, or `None` if it has list properties.
    pub fn fixed_size(&self) -> Option<usize> {
        self.properties
            .iter()
            .try_fold(0usize, |acc, p| match p.kind {
                PlyPropertyKind::Scalar(t) => Some(acc + t.size()),
                PlyPropertyKind::List { .. } => None,
            })
    }
}

/// The parsed header of a PLY file: what [`read_ply_header`](crate::read_ply_header) returns.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct PlyHeader {
    /// Body encoding from the `format` line.
    pub encoding: PlyEncoding,
    /// Version from the `format` line (always `1.0` in practice).
    pub version: String,
    /// Text of the `comment` lines, without the keyword.
    pub comments: Vec<String>,
    /// Text of the `obj_info` lines, without the keyword.
    pub obj_info: Vec<String>,
    /// Elements in file order.
    pub elements: Vec<PlyElement>,
    /// Length of the header in bytes, i.e. offset of the first body byte.
    pub body_offset: u64,
}

impl PlyHeader {
    /// The element called `name`, if any.
    pub fn element(&self, name: &str) -> Option<&PlyElement> {
        self.elements.iter().find(|e| e.name == name)
    }

    /// Number of vertices declared (0 if there is no `vertex` element).
    pub fn vertex_count(&self) -> u64 {
        self.element("vertex").map_or(0, |e| e.count)
    }
}
