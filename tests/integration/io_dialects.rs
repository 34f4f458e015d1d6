//! Every PLY dialect real writers produce decodes to the same mesh; PLY and STL round trips
//! are bit-exact; STL and OBJ readers agree with PLY.

use crate::common;

use common::*;
use destair::io::ply::encode_ply;
use destair::io::stl::encode_stl;
use destair::io::{decode_mesh, LoadedMesh, MeshMeta, ReadOptions, SourceFormat};
use destair::Mesh;

fn decode(bytes: &[u8], ext: &str) -> LoadedMesh {
    decode_mesh(bytes, Some(ext), &ReadOptions::default()).unwrap_or_else(|e| {
        panic!(
            "decode failed: {e}\n{}",
            String::from_utf8_lossy(&bytes[..bytes.len().min(600)])
        )
    })
}

fn layouts() -> Vec<(String, Layout)> {
    let mut out = Vec::new();
    let base = Layout::default();
    for enc in [Enc::Le, Enc::Be, Enc::Ascii] {
        let with = |f: &dyn Fn(&mut Layout)| {
            let mut l = Layout {
                enc,
                ..base.clone()
            };
            f(&mut l);
            l
        };
        out.push((format!("{enc:?} plain"), with(&|_| {})));
        out.push((
            format!("{enc:?} extra vertex properties in any order"),
            with(&|l| {
                l.vertex_props = vec![
                    ("float", "nx"),
                    ("uchar", "red"),
                    ("float", "x"),
                    ("double", "quality"),
                    ("float", "y"),
                    ("uchar", "green"),
                    ("float", "z"),
                    ("float", "ny"),
                ]
            }),
        ));
        out.push((
            format!("{enc:?} double coordinates"),
            with(&|l| l.vertex_props = vec![("double", "x"), ("double", "y"), ("double", "z")]),
        ));
        out.push((
            format!("{enc:?} float32 type names and z before x"),
            with(&|l| l.vertex_props = vec![("float32", "z"), ("float32", "x"), ("float32", "y")]),
        ));
        out.push((
            format!("{enc:?} vertex_index"),
            with(&|l| l.face_name = "vertex_index"),
        ));
        for count_type in ["uchar", "ushort", "int", "uint", "uint8", "char"] {
            for index_type in [
                "char", "uchar", "short", "ushort", "int", "uint", "int32", "uint32",
            ] {
                out.push((
                    format!("{enc:?} list {count_type} {index_type}"),
                    with(&|l| {
                        l.count_type = count_type;
                        l.index_type = index_type;
                    }),
                ));
            }
        }
        out.push((
            format!("{enc:?} face scalars around the list"),
            with(&|l| {
                l.face_scalar_before = true;
                l.face_scalar_after = true;
            }),
        ));
        out.push((
            format!("{enc:?} second face list"),
            with(&|l| l.face_extra_list = true),
        ));
        out.push((
            format!("{enc:?} vertex list property"),
            with(&|l| l.vertex_list = true),
        ));
        out.push((
            format!("{enc:?} other elements"),
            with(&|l| l.other_elements = true),
        ));
        out.push((format!("{enc:?} CRLF header"), with(&|l| l.crlf = true)));
        out.push((format!("{enc:?} quads"), with(&|l| l.quads = true)));
        out.push((
            format!("{enc:?} everything at once"),
            with(&|l| {
                l.vertex_props = vec![
                    ("uchar", "red"),
                    ("double", "z"),
                    ("float", "y"),
                    ("short", "label"),
                    ("float", "x"),
                ];
                l.count_type = "ushort";
                l.index_type = "uint";
                l.face_scalar_before = true;
                l.face_extra_list = true;
                l.other_elements = true;
                l.crlf = true;
                l.quads = true;
            }),
        ));
    }
    out
}

#[test]
fn every_ply_dialect_gives_the_same_mesh() {
    let mesh = reference_mesh();
    let layouts = layouts();
    assert!(layouts.len() > 150);
    for (name, layout) in layouts {
        let (bytes, triangles) = ply_bytes(&mesh, &layout);
        let loaded = decode(&bytes, "ply");
        let expected = Mesh::new(mesh.positions().to_vec(), triangles).unwrap();
        assert!(same_bits(&loaded.mesh, &expected), "{name}: mesh differs");
        assert_eq!(
            loaded.meta.comments,
            vec!["SPACE=LPS", "made by the destair test suite"],
            "{name}"
        );
        assert_eq!(loaded.meta.obj_info, vec!["fixture"], "{name}");
        assert_eq!(loaded.meta.space(), Some("LPS"));
        assert_eq!(
            loaded.format,
            match layout.enc {
                Enc::Le => SourceFormat::PlyBinaryLittleEndian,
                Enc::Be => SourceFormat::PlyBinaryBigEndian,
                Enc::Ascii => SourceFormat::PlyAscii,
            }
        );
        let fanned = loaded
            .warnings
            .iter()
            .any(|w| w.contains("fan-triangulated"));
        assert_eq!(fanned, layout.quads, "{name}: {:?}", loaded.warnings);
        let skipped = loaded
            .warnings
            .iter()
            .any(|w| w.contains("\"edge\" (3 rows) was skipped"));
        assert_eq!(
            skipped, layout.other_elements,
            "{name}: {:?}",
            loaded.warnings
        );
    }
}

#[test]
fn element_face_zero_and_missing_face_element_give_points() {
    let mesh = reference_mesh();
    for enc in [Enc::Le, Enc::Ascii] {
        let layout = Layout {
            enc,
            no_faces: true,
            ..Layout::default()
        };
        let (bytes, _) = ply_bytes(&mesh, &layout);
        let loaded = decode(&bytes, "ply");
        assert_eq!(loaded.mesh.n_triangles(), 0);
        assert_eq!(loaded.mesh.positions(), mesh.positions());
    }
    let only_vertices = b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n";
    let loaded = decode(only_vertices, "ply");
    assert_eq!(loaded.mesh.positions(), &[[1.0, 2.0, 3.0]]);
    assert!(loaded
        .warnings
        .iter()
        .any(|w| w.contains("no 'face' element")));
}

#[test]
fn extra_vertex_properties_are_kept_on_request() {
    let mesh = reference_mesh();
    let layout = Layout {
        vertex_props: vec![
            ("float", "x"),
            ("float", "y"),
            ("float", "z"),
            ("uchar", "label"),
            ("float", "weight"),
        ],
        ..Layout::default()
    };
    for enc in [Enc::Le, Enc::Be, Enc::Ascii] {
        let (bytes, _) = ply_bytes(
            &mesh,
            &Layout {
                enc,
                ..layout.clone()
            },
        );
        let options = ReadOptions {
            keep_vertex_properties: true,
            ..Default::default()
        };
        let loaded = decode_mesh(&bytes, Some("ply"), &options).unwrap();
        let names: Vec<&str> = loaded
            .vertex_properties
            .iter()
            .map(|p| p.name.as_str())
            .collect();
        assert_eq!(names, ["label", "weight"]);
        let expected: Vec<f32> = (0..mesh.n_vertices())
            .map(|i| (i % 5) as f32 + 0.5)
            .collect();
        assert_eq!(loaded.vertex_properties[1].values, expected);
        assert_eq!(loaded.vertex_properties[0].values[3], 3.0);
    }
}

#[test]
fn ply_round_trip_is_bit_exact() {
    let mesh = reference_mesh();
    let meta = MeshMeta {
        comments: vec!["SPACE=RAS".into(), "second".into()],
        obj_info: vec!["info".into()],
    };
    let weights: Vec<f32> = (0..mesh.n_vertices()).map(|i| i as f32 / 7.0).collect();
    let disp: Vec<f32> = (0..mesh.n_vertices()).map(|i| -(i as f32)).collect();
    let props: [(&str, &[f32]); 2] = [("weight", &weights), ("displacement", &disp)];
    let bytes = encode_ply(&mesh, &meta, &props).unwrap();
    let header_end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap();
    let header = std::str::from_utf8(&bytes[..header_end]).unwrap();
    assert!(header.contains("property list uchar int vertex_indices"));
    let options = ReadOptions {
        keep_vertex_properties: true,
        ..Default::default()
    };
    let loaded = decode_mesh(&bytes, Some("ply"), &options).unwrap();
    assert!(same_bits(&loaded.mesh, &mesh));
    assert_eq!(loaded.meta, meta);
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    assert_eq!(loaded.vertex_properties[0].values, weights);
    assert_eq!(loaded.vertex_properties[1].values, disp);
    let again: Vec<(&str, &[f32])> = loaded
        .vertex_properties
        .iter()
        .map(|p| (p.name.as_str(), p.values.as_slice()))
        .collect();
    assert_eq!(
        encode_ply(&loaded.mesh, &loaded.meta, &again).unwrap(),
        bytes
    );
}

#[test]
fn ply_writer_rejects_bad_properties() {
    let mesh = reference_mesh();
    let short = vec![0.0f32; 2];
    let ok = vec![0.0f32; mesh.n_vertices()];
    let meta = MeshMeta::default();
    assert!(encode_ply(&mesh, &meta, &[("w", &short)]).is_err());
    assert!(encode_ply(&mesh, &meta, &[("a b", &ok)]).is_err());
    assert!(encode_ply(&mesh, &meta, &[("x", &ok)]).is_err());
    assert!(encode_ply(&mesh, &meta, &[("w", &ok), ("w", &ok)]).is_err());
}

#[test]
fn stl_round_trip_is_bit_exact_and_ascii_agrees() {
    let mesh = first_appearance(&reference_mesh());
    let meta = MeshMeta {
        comments: vec!["SPACE=LPS".into()],
        obj_info: vec![],
    };
    let bytes = encode_stl(&mesh, &meta);
    assert!(!bytes.starts_with(b"solid"));
    assert!(String::from_utf8_lossy(&bytes[..80]).contains("SPACE=LPS"));
    let loaded = decode(&bytes, "stl");
    assert_eq!(loaded.format, SourceFormat::StlBinary);
    assert!(same_bits(&loaded.mesh, &mesh));
    assert_eq!(loaded.meta.space(), Some("LPS"));
    assert_eq!(encode_stl(&loaded.mesh, &loaded.meta), bytes);

    let ascii = ascii_stl(&mesh, "SPACE=RAS");
    let loaded = decode(&ascii, "stl");
    assert_eq!(loaded.format, SourceFormat::StlAscii);
    assert!(same_bits(&loaded.mesh, &mesh));
    assert_eq!(loaded.meta.space(), Some("RAS"));
    // Detected by content without an extension too.
    assert!(same_bits(&decode(&ascii, "").mesh, &mesh));

    // A binary STL whose header starts with "solid" is still binary.
    let mut solid_header = bytes.clone();
    solid_header[..6].copy_from_slice(b"solid ");
    let loaded = decode(&solid_header, "stl");
    assert_eq!(loaded.format, SourceFormat::StlBinary);
    assert!(same_bits(&loaded.mesh, &mesh));
}

#[test]
fn stl_welds_plus_and_minus_zero() {
    let m = Mesh::new(
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [-0.0, 0.0, 0.0],
        ],
        vec![[0, 1, 2], [3, 2, 1]],
    )
    .unwrap();
    let loaded = decode(&encode_stl(&m, &MeshMeta::default()), "stl");
    assert_eq!(loaded.mesh.n_vertices(), 3);
    assert_eq!(loaded.mesh.triangles(), &[[0, 1, 2], [0, 2, 1]]);
}

#[test]
fn obj_reader_agrees_with_ply() {
    let mesh = reference_mesh();
    let mut s = String::from("# exported by a test\nmtllib none.mtl\no octahedron\n");
    for p in mesh.positions() {
        s.push_str(&format!("v {} {} {} 1.0\n", p[0], p[1], p[2]));
    }
    s.push_str("vn 0 0 1\nvt 0.5 0.5\ng group\nusemtl skin\ns off\n");
    let n = mesh.n_vertices() as i64;
    for (i, t) in mesh.triangles().iter().enumerate() {
        let corner = |v: u32, k: usize| match (i + k) % 4 {
            0 => format!("{}", v + 1),
            1 => format!("{}/1", v + 1),
            2 => format!("{}/1/1", v + 1),
            _ => format!("{}//1", v as i64 - n),
        };
        s.push_str(&format!(
            "f {} {} {}\n",
            corner(t[0], 0),
            corner(t[1], 1),
            corner(t[2], 2)
        ));
    }
    s.push_str("l 1 2\n");
    let loaded = decode(s.as_bytes(), "obj");
    assert_eq!(loaded.format, SourceFormat::Obj);
    assert!(same_bits(&loaded.mesh, &mesh));
    assert!(loaded.warnings.iter().any(|w| w.contains("line and point")));

    let quads = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
    let loaded = decode(quads.as_bytes(), "obj");
    assert_eq!(loaded.mesh.triangles(), &[[0, 1, 2], [0, 2, 3]]);
    assert!(loaded
        .warnings
        .iter()
        .any(|w| w.contains("fan-triangulated")));
}

#[test]
fn files_on_disk_through_mmap_and_plain_read() {
    use destair::io::{read_mesh, ReadMode};
    let dir = tempfile::tempdir().unwrap();
    let mesh = reference_mesh();
    let path = dir.path().join("m.ply");
    destair::io::ply::write_ply(&path, &mesh, &MeshMeta::default(), &[]).unwrap();
    for mode in [ReadMode::Mmap, ReadMode::Read] {
        let options = ReadOptions {
            mode,
            ..Default::default()
        };
        assert!(same_bits(&read_mesh(&path, &options).unwrap().mesh, &mesh));
    }
    let stl = dir.path().join("m.STL");
    destair::io::stl::write_stl(&stl, &mesh, &MeshMeta::default()).unwrap();
    let loaded = read_mesh(&stl, &ReadOptions::default()).unwrap();
    assert!(same_bits(&loaded.mesh, &first_appearance(&mesh)));
    // Only the two outputs: no temp files left behind.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
}
