//! Tests of `src/io/ply/header.rs`.

use destair::io::ply::header::*;
use destair::io::ReadErrorKind;

#[test]
fn parses_crlf_comments_and_lists() {
    let h = b"ply\r\nformat binary_little_endian 1.0\r\ncomment SPACE=LPS\r\nobj_info made by hand\r\nelement vertex 0\r\nproperty float x\r\nelement face 0\r\nproperty list uchar int vertex_indices\r\nend_header\r\n";
    let header = parse_header(h).unwrap();
    assert_eq!(header.encoding, Encoding::BinaryLittleEndian);
    assert_eq!(header.comments, vec!["SPACE=LPS"]);
    assert_eq!(header.obj_info, vec!["made by hand"]);
    assert_eq!(header.data_start, h.len());
    assert_eq!(
        header.elements[1].properties[0].ty,
        PropertyType::List {
            count: ScalarType::U8,
            item: ScalarType::I32
        }
    );
}

#[test]
fn rejects_duplicates_and_lying_counts() {
    let dup = b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float x\nend_header\n";
    assert!(
        matches!(
            parse_header(dup),
            Err(ReadErrorKind::Header { line: 5, .. })
        ),
        "{:?}",
        parse_header(dup)
    );
    let huge = b"ply\nformat binary_little_endian 1.0\nelement vertex 1099511627776\nproperty float x\nend_header\n";
    assert!(matches!(
        parse_header(huge),
        Err(ReadErrorKind::SizeMismatch { .. })
    ));
    let no_end = b"ply\nformat ascii 1.0\nelement vertex 1\n";
    assert!(matches!(
        parse_header(no_end),
        Err(ReadErrorKind::Header { .. })
    ));
}
