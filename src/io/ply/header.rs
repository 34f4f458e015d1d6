//! The PLY header, parsed by hand so that every problem names its line, duplicate element or
//! property names are rejected (they silently shift the row layout in readers that key
//! properties by name), and declared sizes can be checked against the file before decoding.

use crate::io::ReadErrorKind;

/// Maximum header size; real headers are a few hundred bytes.
const MAX_HEADER_BYTES: usize = 1 << 20;

/// How the data after the header is stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoding {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

/// A PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScalarType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl ScalarType {
    fn parse(name: &str) -> Option<ScalarType> {
        Some(match name {
            "char" | "int8" => ScalarType::I8,
            "uchar" | "uint8" => ScalarType::U8,
            "short" | "int16" => ScalarType::I16,
            "ushort" | "uint16" => ScalarType::U16,
            "int" | "int32" => ScalarType::I32,
            "uint" | "uint32" => ScalarType::U32,
            "float" | "float32" => ScalarType::F32,
            "double" | "float64" => ScalarType::F64,
            _ => return None,
        })
    }

    /// Size in bytes in binary files.
    pub fn size(self) -> usize {
        match self {
            ScalarType::I8 | ScalarType::U8 => 1,
            ScalarType::I16 | ScalarType::U16 => 2,
            ScalarType::I32 | ScalarType::U32 | ScalarType::F32 => 4,
            ScalarType::F64 => 8,
        }
    }

    /// Whether the type holds integers (usable as counts and indices).
    pub fn is_integer(self) -> bool {
        !matches!(self, ScalarType::F32 | ScalarType::F64)
    }

    /// Smallest and largest value of an integer type.
    pub(crate) fn integer_range(self) -> (i64, i64) {
        match self {
            ScalarType::I8 => (i8::MIN as i64, i8::MAX as i64),
            ScalarType::U8 => (0, u8::MAX as i64),
            ScalarType::I16 => (i16::MIN as i64, i16::MAX as i64),
            ScalarType::U16 => (0, u16::MAX as i64),
            ScalarType::I32 => (i32::MIN as i64, i32::MAX as i64),
            ScalarType::U32 => (0, u32::MAX as i64),
            ScalarType::F32 | ScalarType::F64 => (i64::MIN, i64::MAX),
        }
    }
}

/// A property's type: one scalar, or a list with its count and item types.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PropertyType {
    Scalar(ScalarType),
    List { count: ScalarType, item: ScalarType },
}

/// One `property` line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PropertyDef {
    pub name: String,
    pub ty: PropertyType,
}

/// One `element` line and its properties.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ElementDef {
    pub name: String,
    pub count: u64,
    pub properties: Vec<PropertyDef>,
    /// Header line of the `element` statement, for error messages.
    pub line: usize,
}

impl ElementDef {
    /// Bytes per row when every property is a scalar (binary files).
    pub fn fixed_stride(&self) -> Option<usize> {
        self.properties
            .iter()
            .map(|p| match p.ty {
                PropertyType::Scalar(t) => Some(t.size()),
                PropertyType::List { .. } => None,
            })
            .sum()
    }

    /// The fewest bytes one row can take: scalars, plus list counts with empty lists.
    fn min_binary_row(&self) -> u64 {
        self.properties
            .iter()
            .map(|p| match p.ty {
                PropertyType::Scalar(t) => t.size() as u64,
                PropertyType::List { count, .. } => count.size() as u64,
            })
            .sum()
    }

    /// Index of the property with this name.
    pub fn property(&self, name: &str) -> Option<usize> {
        self.properties.iter().position(|p| p.name == name)
    }
}

/// A parsed PLY header.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Header {
    pub encoding: Encoding,
    pub elements: Vec<ElementDef>,
    pub comments: Vec<String>,
    pub obj_info: Vec<String>,
    /// Byte offset where the data section starts.
    pub data_start: usize,
    /// Number of header lines (the data section of an ASCII file starts on the next line).
    pub n_lines: usize,
}

impl Header {
    /// The element with this name.
    pub fn element(&self, name: &str) -> Option<&ElementDef> {
        self.elements.iter().find(|e| e.name == name)
    }
}

fn header_error(line: usize, message: impl Into<String>) -> ReadErrorKind {
    ReadErrorKind::Header {
        line,
        message: message.into(),
    }
}

/// Parses the header at the start of `bytes` and checks the declared element sizes against
/// the bytes that follow it, so nothing is allocated for counts the file cannot hold.
pub fn parse_header(bytes: &[u8]) -> Result<Header, ReadErrorKind> {
    let mut lines = bytes.split_inclusive(|&b| b == b'\n');
    let mut offset = 0usize;
    let mut line_no = 0usize;
    let mut encoding = None;
    let mut elements: Vec<ElementDef> = Vec::new();
    let mut comments = Vec::new();
    let mut obj_info = Vec::new();
    loop {
        let Some(raw) = lines.next() else {
            return Err(header_error(
                line_no,
                "header has no end_header line (file is truncated or not a PLY file)",
            ));
        };
        if !raw.ends_with(b"\n") {
            return Err(header_error(
                line_no + 1,
                "header has no end_header line (file is truncated or not a PLY file)",
            ));
        }
        line_no += 1;
        offset += raw.len();
        if offset > MAX_HEADER_BYTES {
            return Err(header_error(line_no, "header is longer than 1 MiB"));
        }
        let raw = raw.strip_suffix(b"\n").unwrap_or(raw);
        let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
        let Ok(text) = std::str::from_utf8(raw) else {
            return Err(header_error(line_no, "header line is not text"));
        };
        if line_no == 1 {
            if text.trim_end() != "ply" {
                return Err(header_error(
                    1,
                    "file does not start with the 'ply' magic line",
                ));
            }
            continue;
        }
        let mut words = text.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        match keyword {
            "format" => {
                if encoding.is_some() {
                    return Err(header_error(line_no, "second format line"));
                }
                let enc = match words.next() {
                    Some("ascii") => Encoding::Ascii,
                    Some("binary_little_endian") => Encoding::BinaryLittleEndian,
                    Some("binary_big_endian") => Encoding::BinaryBigEndian,
                    other => {
                        return Err(header_error(
                            line_no,
                            format!("unknown format {:?} (expected ascii, binary_little_endian or binary_big_endian)", other.unwrap_or("")),
                        ))
                    }
                };
                match words.next() {
                    Some(v) if v.starts_with('1') => {}
                    other => {
                        return Err(header_error(
                            line_no,
                            format!("unsupported PLY version {:?}", other.unwrap_or("")),
                        ))
                    }
                }
                encoding = Some(enc);
            }
            "comment" => comments.push(after_keyword(text, "comment")),
            "obj_info" => obj_info.push(after_keyword(text, "obj_info")),
            "element" => {
                let (Some(name), Some(count), None) = (words.next(), words.next(), words.next())
                else {
                    return Err(header_error(line_no, "expected 'element NAME COUNT'"));
                };
                let count: u64 = count.parse().map_err(|_| {
                    header_error(
                        line_no,
                        format!("element {name}: count {count:?} is not a non-negative integer"),
                    )
                })?;
                if elements.iter().any(|e| e.name == name) {
                    return Err(header_error(
                        line_no,
                        format!("element {name:?} is declared twice"),
                    ));
                }
                elements.push(ElementDef {
                    name: name.to_string(),
                    count,
                    properties: Vec::new(),
                    line: line_no,
                });
            }
            "property" => {
                let Some(element) = elements.last_mut() else {
                    return Err(header_error(line_no, "property before any element"));
                };
                let words: Vec<&str> = words.collect();
                let (ty, name) = match words.as_slice() {
                    ["list", count, item, name] => {
                        let count = scalar_type(line_no, count)?;
                        let item = scalar_type(line_no, item)?;
                        if !count.is_integer() {
                            return Err(header_error(
                                line_no,
                                format!("list {name:?} has a non-integer count type"),
                            ));
                        }
                        (PropertyType::List { count, item }, *name)
                    }
                    [ty, name] if *ty != "list" => {
                        (PropertyType::Scalar(scalar_type(line_no, ty)?), *name)
                    }
                    _ => {
                        return Err(header_error(
                            line_no,
                            "expected 'property TYPE NAME' or 'property list COUNT_TYPE ITEM_TYPE NAME'",
                        ))
                    }
                };
                if element.property(name).is_some() {
                    return Err(header_error(
                        line_no,
                        format!(
                            "element {}: property {name:?} is declared twice",
                            element.name
                        ),
                    ));
                }
                element.properties.push(PropertyDef {
                    name: name.to_string(),
                    ty,
                });
            }
            "end_header" => break,
            other => {
                return Err(header_error(
                    line_no,
                    format!(
                        "unknown header keyword {:?}",
                        crate::io::text::show(other.as_bytes())
                    ),
                ))
            }
        }
    }
    let Some(encoding) = encoding else {
        return Err(header_error(line_no, "header has no format line"));
    };
    let header = Header {
        encoding,
        elements,
        comments,
        obj_info,
        data_start: offset,
        n_lines: line_no,
    };
    check_sizes(&header, bytes.len() - offset)?;
    Ok(header)
}

fn after_keyword(text: &str, keyword: &str) -> String {
    let rest = text.trim_start();
    let rest = &rest[keyword.len()..];
    rest.strip_prefix(' ').unwrap_or(rest).to_string()
}

fn scalar_type(line: usize, name: &str) -> Result<ScalarType, ReadErrorKind> {
    ScalarType::parse(name)
        .ok_or_else(|| header_error(line, format!("unknown property type {name:?}")))
}

/// Rejects headers whose element counts need more bytes than follow the header.
fn check_sizes(header: &Header, data_len: usize) -> Result<(), ReadErrorKind> {
    let mut needed: u128 = 0;
    for e in &header.elements {
        let row = match header.encoding {
            // Each value takes at least one character and one separator.
            Encoding::Ascii => 2 * e.properties.len() as u128,
            _ => e.min_binary_row() as u128,
        };
        let element_needs = row * e.count as u128;
        needed += element_needs;
        // In ASCII the last value of the file may lack a trailing separator.
        if needed > data_len as u128 + 1 {
            return Err(ReadErrorKind::SizeMismatch {
                message: format!(
                    "element {:?} (header line {}) declares {} rows needing at least {} bytes, but only {} bytes follow the header",
                    e.name, e.line, e.count, element_needs, data_len
                ),
            });
        }
    }
    Ok(())
}
