//! Fixtures shared by the integration tests: a reference mesh and writers for every PLY
//! dialect the reader must accept, built byte by byte so they do not depend on destair's writer.
#![allow(dead_code)]

pub mod cohort;

use destair::Mesh;

/// An octahedron with awkward float values, plus one unreferenced vertex at the end.
pub fn reference_mesh() -> Mesh {
    let p = vec![
        [1.25, 0.0, 0.0],
        [-1.0e-3, 0.0, -0.0],
        [0.0, 3.1415925, 0.0],
        [0.0, -2.5e-7, 0.0],
        [0.0, 0.0, 123456.78],
        [0.0, 0.1, -7.75],
        [9.0, 9.0, 9.0],
    ];
    // Consecutive pairs (a,b,c),(a,c,d) so the quad layouts can merge them.
    let t = vec![
        [4, 0, 2],
        [4, 2, 1],
        [4, 1, 3],
        [4, 3, 0],
        [5, 2, 0],
        [5, 0, 3],
        [5, 3, 1],
        [5, 1, 2],
    ];
    Mesh::new(p, t).unwrap()
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Enc {
    Ascii,
    Le,
    Be,
}

/// How to lay out a PLY file of the reference mesh.
#[derive(Clone, Debug)]
pub struct Layout {
    pub enc: Enc,
    /// Vertex properties as (type, name); x, y, z must be among them. Others get filler values.
    pub vertex_props: Vec<(&'static str, &'static str)>,
    /// A list property inside the vertex element (forces the general decoder).
    pub vertex_list: bool,
    pub count_type: &'static str,
    pub index_type: &'static str,
    pub face_name: &'static str,
    pub face_scalar_before: bool,
    pub face_scalar_after: bool,
    /// An extra list property in the face element (forces the general decoder).
    pub face_extra_list: bool,
    /// Elements that are not vertex or face, before and after the mesh ones.
    pub other_elements: bool,
    pub crlf: bool,
    /// Write each pair of triangles sharing an edge as one quad where possible.
    pub quads: bool,
    pub no_faces: bool,
}

impl Default for Layout {
    fn default() -> Self {
        Layout {
            enc: Enc::Le,
            vertex_props: vec![("float", "x"), ("float", "y"), ("float", "z")],
            vertex_list: false,
            count_type: "uchar",
            index_type: "int",
            face_name: "vertex_indices",
            face_scalar_before: false,
            face_scalar_after: false,
            face_extra_list: false,
            other_elements: false,
            crlf: false,
            quads: false,
            no_faces: false,
        }
    }
}

/// Appends one value of PLY type `ty` in the layout's encoding.
pub fn put(out: &mut Vec<u8>, enc: Enc, ty: &str, v: f64) {
    if enc == Enc::Ascii {
        let text = match ty {
            "float" | "float32" => format!("{}", v as f32),
            "double" | "float64" => format!("{v}"),
            _ => format!("{}", v as i64),
        };
        out.extend_from_slice(text.as_bytes());
        out.push(b' ');
        return;
    }
    macro_rules! e {
        ($x:expr) => {
            if enc == Enc::Le {
                out.extend_from_slice(&$x.to_le_bytes())
            } else {
                out.extend_from_slice(&$x.to_be_bytes())
            }
        };
    }
    match ty {
        "char" | "int8" => e!(v as i8),
        "uchar" | "uint8" => e!(v as u8),
        "short" | "int16" => e!(v as i16),
        "ushort" | "uint16" => e!(v as u16),
        "int" | "int32" => e!(v as i32),
        "uint" | "uint32" => e!(v as u32),
        "float" | "float32" => e!(v as f32),
        "double" | "float64" => e!(v),
        other => panic!("unknown type {other}"),
    }
}

fn end_row(out: &mut Vec<u8>, enc: Enc) {
    if enc == Enc::Ascii {
        out.pop();
        out.push(b'\n');
    }
}

/// The polygons the layout writes, and the triangles the reader must produce from them.
pub fn polygons(mesh: &Mesh, quads: bool) -> (Vec<Vec<u32>>, Vec<[u32; 3]>) {
    let t = mesh.triangles();
    if !quads {
        return (t.iter().map(|t| t.to_vec()).collect(), t.to_vec());
    }
    // Triangles (a,b,c),(a,c,d) -> quad (a,b,c,d) fans back into the same two triangles.
    let mut polys = Vec::new();
    let mut tris = Vec::new();
    let mut i = 0;
    while i < t.len() {
        if i + 1 < t.len() {
            let (x, y) = (t[i], t[i + 1]);
            if y[0] == x[0] && y[1] == x[2] {
                polys.push(vec![x[0], x[1], x[2], y[2]]);
                tris.extend([x, y]);
                i += 2;
                continue;
            }
        }
        polys.push(t[i].to_vec());
        tris.push(t[i]);
        i += 1;
    }
    (polys, tris)
}

/// Writes the mesh in the given layout; returns the bytes and the triangles expected back.
pub fn ply_bytes(mesh: &Mesh, l: &Layout) -> (Vec<u8>, Vec<[u32; 3]>) {
    let nl = if l.crlf { "\r\n" } else { "\n" };
    let (polys, expected) = polygons(mesh, l.quads);
    let mut h = String::new();
    let mut line = |s: &str| {
        h.push_str(s);
        h.push_str(nl);
    };
    line("ply");
    line(match l.enc {
        Enc::Ascii => "format ascii 1.0",
        Enc::Le => "format binary_little_endian 1.0",
        Enc::Be => "format binary_big_endian 1.0",
    });
    line("comment SPACE=LPS");
    line("comment made by the destair test suite");
    line("obj_info fixture");
    if l.other_elements {
        line("element material 2");
        line("property uchar ambient_red");
        line("property float shininess");
    }
    line(&format!("element vertex {}", mesh.n_vertices()));
    for (ty, name) in &l.vertex_props {
        line(&format!("property {ty} {name}"));
    }
    if l.vertex_list {
        line("property list uchar float texcoords");
    }
    if !l.no_faces {
        line(&format!("element face {}", polys.len()));
        if l.face_scalar_before {
            line("property uchar red");
        }
        line(&format!(
            "property list {} {} {}",
            l.count_type, l.index_type, l.face_name
        ));
        if l.face_extra_list {
            line("property list uchar float texcoord");
        }
        if l.face_scalar_after {
            line("property double quality");
        }
    } else {
        line("element face 0");
        line("property list uchar int vertex_indices");
    }
    if l.other_elements {
        line("element edge 3");
        line("property list uchar int vertex_pair");
        line("property uchar red");
    }
    line("end_header");
    let mut out = h.into_bytes();
    let enc = l.enc;
    if l.other_elements {
        for m in 0..2 {
            put(&mut out, enc, "uchar", 200.0 + m as f64);
            put(&mut out, enc, "float", 0.5);
            end_row(&mut out, enc);
        }
    }
    for (i, p) in mesh.positions().iter().enumerate() {
        for (ty, name) in &l.vertex_props {
            let v = match *name {
                "x" => p[0] as f64,
                "y" => p[1] as f64,
                "z" => p[2] as f64,
                _ => (i % 5) as f64 + 0.5 * (ty.starts_with('f') || ty == &"double") as i32 as f64,
            };
            put(&mut out, enc, ty, v);
        }
        if l.vertex_list {
            put(&mut out, enc, "uchar", (i % 3) as f64);
            for k in 0..i % 3 {
                put(&mut out, enc, "float", k as f64 * 0.25);
            }
        }
        end_row(&mut out, enc);
    }
    if !l.no_faces {
        for (i, poly) in polys.iter().enumerate() {
            if l.face_scalar_before {
                put(&mut out, enc, "uchar", (i * 17 % 256) as f64);
            }
            put(&mut out, enc, l.count_type, poly.len() as f64);
            for &v in poly {
                put(&mut out, enc, l.index_type, v as f64);
            }
            if l.face_extra_list {
                put(&mut out, enc, "uchar", 2.0);
                put(&mut out, enc, "float", 0.1);
                put(&mut out, enc, "float", 0.2);
            }
            if l.face_scalar_after {
                put(&mut out, enc, "double", i as f64 * 0.5);
            }
            end_row(&mut out, enc);
        }
    }
    if l.other_elements {
        for e in 0..3u32 {
            put(&mut out, enc, "uchar", 2.0);
            put(&mut out, enc, "int", e as f64);
            put(&mut out, enc, "int", (e + 1) as f64);
            put(&mut out, enc, "uchar", 7.0);
            end_row(&mut out, enc);
        }
    }
    (out, if l.no_faces { Vec::new() } else { expected })
}

/// The mesh as ASCII STL, one facet per triangle.
pub fn ascii_stl(mesh: &Mesh, name: &str) -> Vec<u8> {
    let p = mesh.positions();
    let mut s = format!("solid {name}\n");
    for t in mesh.triangles() {
        s.push_str("  facet normal 0 0 1\n    outer loop\n");
        for &v in t {
            let q = p[v as usize];
            s.push_str(&format!("      vertex {} {} {}\n", q[0], q[1], q[2]));
        }
        s.push_str("    endloop\n  endfacet\n");
    }
    s.push_str(&format!("endsolid {name}\n"));
    s.into_bytes()
}

/// The reference mesh renumbered in order of first appearance in its triangles, without the
/// unreferenced vertex: what STL (which has no shared vertices) can carry.
pub fn first_appearance(mesh: &Mesh) -> Mesh {
    let all: Vec<u32> = (0..mesh.n_triangles() as u32).collect();
    mesh.select_faces(&all)
}

/// Bitwise equality of positions (so -0.0 != 0.0 and NaN payloads count).
pub fn same_bits(a: &Mesh, b: &Mesh) -> bool {
    a.n_vertices() == b.n_vertices()
        && a.positions()
            .iter()
            .zip(b.positions())
            .all(|(p, q)| p.map(f32::to_bits) == q.map(f32::to_bits))
        && a.triangles() == b.triangles()
}

/// A unit cube (outward) without its two top triangles: one open square loop at z = 1.
pub fn open_box() -> Mesh {
    let p: Vec<[f32; 3]> = (0..8)
        .map(|i| [(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32])
        .collect();
    let quads = [
        [0, 2, 3, 1],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let t = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    Mesh::new(p, t).unwrap()
}

/// A sphere of `radius` mm made by subdividing an icosahedron `levels` times (20 * 4^levels faces).
pub fn icosphere(levels: usize, radius: f32) -> destair::Mesh {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut p: Vec<[f32; 3]> = vec![
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ];
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let unit = |v: [f32; 3]| {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v.map(|x| x / l)
    };
    for q in &mut p {
        *q = unit(*q);
    }
    for _ in 0..levels {
        let mut mid = std::collections::HashMap::new();
        let mut next = Vec::new();
        for tri in &f {
            let mut m = [0u32; 3];
            for k in 0..3 {
                let (a, b) = (tri[k].min(tri[(k + 1) % 3]), tri[k].max(tri[(k + 1) % 3]));
                m[k] = *mid.entry((a, b)).or_insert_with(|| {
                    let (pa, pb) = (p[a as usize], p[b as usize]);
                    p.push(unit([pa[0] + pb[0], pa[1] + pb[1], pa[2] + pb[2]]));
                    (p.len() - 1) as u32
                });
            }
            next.extend([
                [tri[0], m[0], m[2]],
                [tri[1], m[1], m[0]],
                [tri[2], m[2], m[1]],
                [m[0], m[1], m[2]],
            ]);
        }
        f = next;
    }
    destair::Mesh::new(p.iter().map(|q| q.map(|x| x * radius)).collect(), f).unwrap()
}

/// The aneurysm phantom's vessel, with its ends capped or open, rotated (degrees).
pub fn aneurysm(ends: destair::phantom::marching_cubes::BorderEnds, rx: f64, ry: f64) -> Mesh {
    let case = destair::phantom::named_case(
        "aneurysm",
        &destair::phantom::PhantomOptions {
            rotate_x_deg: rx,
            rotate_y_deg: ry,
            ends,
            ..Default::default()
        },
    )
    .unwrap();
    case.meshes[0].1.clone()
}
