//! Tests of `src/io/vtp.rs`.

use destair::io::vtp::*;
use destair::io::MeshMeta;
use destair::mesh::Mesh;

#[test]
fn arrays_of_the_wrong_length_are_refused() {
    let m = Mesh::new(
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        vec![[0, 1, 2]],
    )
    .unwrap();
    let meta = MeshMeta::default();
    let e = encode_vtp(&m, &meta, &[VtpArray::Float32("weight", &[1.0])], &[]).unwrap_err();
    assert!(
        e.to_string()
            .contains("array \"weight\": 1 values for 3 vertices"),
        "{e}"
    );
    let e = encode_vtp(&m, &meta, &[], &[VtpArray::Int32("CellEntityIds", &[])]).unwrap_err();
    assert!(e.to_string().contains("for 1 faces"), "{e}");
    let ok = encode_vtp(&m, &meta, &[VtpArray::Float32("w", &[0.5; 3])], &[]).unwrap();
    let text = String::from_utf8_lossy(&ok);
    assert!(text.contains("<PointData Scalars=\"w\">"));
    assert!(text.contains("NumberOfPoints=\"3\""));
    assert!(text.ends_with("</VTKFile>\n"));
}
