//! Corrupt, lying and random input: every reader returns an error (never panics, never hangs)
//! and allocates no more than a small multiple of the file size, whatever the header claims.

use crate::common;

use common::*;
use destair::io::ply::encode_ply;
use destair::io::stl::encode_stl;
use destair::io::{decode_mesh, LoadedMesh, MeshMeta, ReadErrorKind, ReadOptions};
use std::alloc::{GlobalAlloc, Layout as AllocLayout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, OnceLock};

/// Counts the live heap bytes of the measuring thread and their peak, so tests can bound what
/// a decode allocates. Only the thread that decodes is counted: the other tests of this binary
/// run beside these ones and allocate at the same time (which made the bound fail spuriously).
struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);
/// Memory measurements use the one measuring thread one at a time.
static SERIAL: Mutex<()> = Mutex::new(());

thread_local! {
    /// Set on the thread whose allocations are counted.
    static MEASURED: Cell<bool> = const { Cell::new(false) };
}

fn measured() -> bool {
    MEASURED.try_with(Cell::get).unwrap_or(false)
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: AllocLayout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() && measured() {
            let now = LIVE.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
            PEAK.fetch_max(now, Ordering::Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: AllocLayout) {
        unsafe { System.dealloc(ptr, layout) };
        if measured() {
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: AllocLayout, new_size: usize) -> *mut u8 {
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() && measured() {
            if new_size >= layout.size() {
                let now = LIVE.fetch_add(new_size - layout.size(), Ordering::Relaxed)
                    + (new_size - layout.size());
                PEAK.fetch_max(now, Ordering::Relaxed);
            } else {
                LIVE.fetch_sub(layout.size() - new_size, Ordering::Relaxed);
            }
        }
        p
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// A one-thread pool for the measured decodes: whatever the decoder runs in parallel runs on
/// that one thread, so all its allocations are counted.
fn measuring_pool() -> &'static rayon::ThreadPool {
    static POOL: OnceLock<rayon::ThreadPool> = OnceLock::new();
    POOL.get_or_init(|| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
    })
}

/// Decodes with the allocation peak measured; panics are caught and reported with the input.
fn decode_measured(bytes: &[u8], ext: &str) -> (Result<LoadedMesh, ReadErrorKind>, usize) {
    let (result, peak) = measuring_pool().install(|| {
        let baseline = LIVE.load(Ordering::Relaxed);
        PEAK.store(baseline, Ordering::Relaxed);
        MEASURED.with(|m| m.set(true));
        let result =
            std::panic::catch_unwind(|| decode_mesh(bytes, Some(ext), &ReadOptions::default()));
        MEASURED.with(|m| m.set(false));
        (result, PEAK.load(Ordering::Relaxed) - baseline)
    });
    match result {
        Ok(r) => (r, peak),
        Err(_) => panic!(
            "decoder panicked on {} bytes ({ext}): {:?}",
            bytes.len(),
            String::from_utf8_lossy(&bytes[..bytes.len().min(300)])
        ),
    }
}

/// The allocation a decode may make: a small multiple of the input, plus fixed overhead.
fn memory_bound(len: usize) -> usize {
    32 * len + (256 << 10)
}

fn check(bytes: &[u8], ext: &str) -> Result<LoadedMesh, ReadErrorKind> {
    let (result, peak) = decode_measured(bytes, ext);
    assert!(
        peak <= memory_bound(bytes.len()),
        "decode of {} bytes ({ext}) allocated {peak} bytes",
        bytes.len()
    );
    if let Ok(loaded) = &result {
        // Whatever decodes must be a valid mesh that the rest of destair can take.
        destair::Mesh::new(
            loaded.mesh.positions().to_vec(),
            loaded.mesh.triangles().to_vec(),
        )
        .expect("decoded mesh fails validation");
        let topology = destair::Topology::build(&loaded.mesh);
        let report =
            destair::report::inspect::inspect(std::path::Path::new("x"), loaded, &topology);
        assert!(report.area_mm2.is_finite());
    }
    result
}

fn warm_up() {
    // Start rayon's pool outside any measurement.
    let _ = decode_mesh(
        &encode_ply(&reference_mesh(), &MeshMeta::default(), &[]).unwrap(),
        Some("ply"),
        &ReadOptions::default(),
    );
}

fn valid_files() -> Vec<(&'static str, &'static str, Vec<u8>)> {
    let mesh = reference_mesh();
    let ply = |enc| {
        ply_bytes(
            &mesh,
            &Layout {
                enc,
                ..Layout::default()
            },
        )
        .0
    };
    let general = ply_bytes(
        &mesh,
        &Layout {
            vertex_list: true,
            face_extra_list: true,
            other_elements: true,
            quads: true,
            ..Layout::default()
        },
    )
    .0;
    let mut obj = String::new();
    for p in mesh.positions() {
        obj.push_str(&format!("v {} {} {}\n", p[0], p[1], p[2]));
    }
    for t in mesh.triangles() {
        obj.push_str(&format!(
            "f {} {}/2 -{}\n",
            t[0] + 1,
            t[1] + 1,
            mesh.n_vertices() as u32 - t[2]
        ));
    }
    vec![
        ("ply binary le", "ply", ply(Enc::Le)),
        ("ply binary be", "ply", ply(Enc::Be)),
        ("ply ascii", "ply", ply(Enc::Ascii)),
        ("ply general path", "ply", general),
        ("stl binary", "stl", encode_stl(&mesh, &MeshMeta::default())),
        ("stl ascii", "stl", ascii_stl(&mesh, "x")),
        ("obj", "obj", obj.into_bytes()),
    ]
}

#[test]
fn truncation_at_every_offset() {
    let _guard = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    warm_up();
    for (name, ext, bytes) in valid_files() {
        let (decoded, peak) = decode_measured(&bytes, ext);
        let mesh =
            decoded.unwrap_or_else(|e| panic!("{name}: the untouched file must decode: {e}"));
        // The counter sees at least the decoded mesh's own arrays.
        let arrays = std::mem::size_of_val(mesh.mesh.positions())
            + std::mem::size_of_val(mesh.mesh.triangles());
        assert!(peak >= arrays, "{name}: measured {peak} bytes < {arrays}");
        assert!(check(&bytes, ext).is_ok());
        for cut in 0..bytes.len() {
            let result = check(&bytes[..cut], ext);
            let binary = name.contains("binary") || name.contains("general");
            if binary {
                assert!(
                    result.is_err(),
                    "{name}: truncated at {cut} of {} decoded",
                    bytes.len()
                );
            }
        }
    }
}

fn header(body: &str) -> Vec<u8> {
    format!("ply\nformat binary_little_endian 1.0\n{body}end_header\n").into_bytes()
}

fn expect_err(bytes: &[u8], ext: &str, what: &str) -> String {
    match check(bytes, ext) {
        Ok(_) => panic!("{what}: decoded"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn lying_headers_and_bad_values() {
    let _guard = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    warm_up();
    let xyz = "property float x\nproperty float y\nproperty float z\n";
    let face = "property list uchar int vertex_indices\n";
    // 2^40 vertices with almost no data.
    let mut huge = header(&format!(
        "element vertex 1099511627776\n{xyz}element face 0\n{face}"
    ));
    huge.extend_from_slice(&[0u8; 36]);
    let msg = expect_err(&huge, "ply", "2^40 vertices");
    assert!(msg.contains("declares 1099511627776 rows"), "{msg}");
    // 2^40 faces.
    let mut faces = header(&format!(
        "element vertex 3\n{xyz}element face 1099511627776\n{face}"
    ));
    faces.extend_from_slice(&[0u8; 36 + 13]);
    expect_err(&faces, "ply", "2^40 faces");
    // u64 overflow in the count itself.
    let overflow = header(&format!("element vertex 99999999999999999999999\n{xyz}"));
    expect_err(&overflow, "ply", "count overflow");
    // 4 billion vertices in a list count inside a small file.
    let mut list = header(&format!(
        "element vertex 3\n{xyz}element face 1\nproperty list uint int vertex_indices\n"
    ));
    list.extend_from_slice(&[0u8; 36]);
    list.extend_from_slice(&u32::MAX.to_le_bytes());
    list.extend_from_slice(&[0u8; 12]);
    let msg = expect_err(&list, "ply", "huge list");
    assert!(msg.contains("face 0"), "{msg}");
    // ASCII: huge count with tiny data.
    let ascii =
        format!("ply\nformat ascii 1.0\nelement vertex 4000000000\n{xyz}end_header\n0 0 0\n");
    expect_err(ascii.as_bytes(), "ply", "ascii huge count");

    // Bad indices, binary and ASCII, fast and general path.
    let mesh = reference_mesh();
    for enc in [Enc::Le, Enc::Be, Enc::Ascii] {
        for extra_list in [false, true] {
            let layout = Layout {
                enc,
                face_extra_list: extra_list,
                ..Layout::default()
            };
            let (mut bytes, _) = ply_bytes(&mesh, &layout);
            // Replace the last face's last index with an out-of-range one.
            let n = mesh.n_vertices() as i32;
            for bad in [n, -1, i32::MAX] {
                let mut b = bytes.clone();
                match enc {
                    Enc::Ascii => {
                        let text = String::from_utf8(b).unwrap();
                        let mut lines: Vec<String> = text.lines().map(String::from).collect();
                        let last = lines.len() - 1;
                        let mut words: Vec<String> =
                            lines[last].split(' ').map(String::from).collect();
                        words[3] = bad.to_string();
                        lines[last] = words.join(" ");
                        b = (lines.join("\n") + "\n").into_bytes();
                    }
                    _ => {
                        let tail = if extra_list { 9 } else { 0 };
                        let at = b.len() - tail - 4;
                        let v = if enc == Enc::Le {
                            bad.to_le_bytes()
                        } else {
                            bad.to_be_bytes()
                        };
                        b[at..at + 4].copy_from_slice(&v);
                    }
                }
                let msg = expect_err(&b, "ply", "bad index");
                assert!(
                    msg.contains("face 7") && msg.contains("out of range"),
                    "{enc:?} {extra_list}: {msg}"
                );
            }
            // NaN and infinity in the first vertex.
            for bad in [f32::NAN, f32::INFINITY] {
                let text_start = bytes
                    .windows(11)
                    .position(|w| w == b"end_header\n")
                    .unwrap()
                    + 11;
                match enc {
                    Enc::Ascii => {
                        let token = if bad.is_nan() { "nan" } else { "inf" };
                        let mut s = String::from_utf8(bytes.clone()).unwrap();
                        let line_end = s[text_start..].find('\n').unwrap() + text_start;
                        s.replace_range(text_start..line_end, &format!("{token} 0 0"));
                        let msg = expect_err(s.as_bytes(), "ply", "nan ascii");
                        assert!(
                            msg.contains("vertex 0") && msg.contains("not a finite"),
                            "{msg}"
                        );
                    }
                    _ => {
                        let v = if enc == Enc::Le {
                            bad.to_le_bytes()
                        } else {
                            bad.to_be_bytes()
                        };
                        bytes[text_start + 4..text_start + 8].copy_from_slice(&v);
                        let msg = expect_err(&bytes, "ply", "nan binary");
                        assert!(
                            msg.contains("vertex 0") && msg.contains("not a finite"),
                            "{msg}"
                        );
                    }
                }
            }
        }
    }
    // Double coordinates that overflow f32: finite, but far beyond +-1e7 mm.
    let mut big =
        header("element vertex 1\nproperty double x\nproperty double y\nproperty double z\n");
    for v in [1e300f64, 0.0, 0.0] {
        big.extend_from_slice(&v.to_le_bytes());
    }
    let msg = expect_err(&big, "ply", "f64 overflow");
    assert!(
        msg.contains("vertex 0") && msg.contains("1.000e300 mm lies beyond +-1e7 mm"),
        "{msg}"
    );
}

/// A tetrahedron with vertex 0 at x = `x`, in each format a reader decodes: (name, extension,
/// bytes, place the error must name). Written by hand: the writers take a `Mesh`, which cannot
/// hold the invalid coordinates these files must carry.
fn tetrahedra_with_x(x: f64) -> Vec<(&'static str, &'static str, Vec<u8>, &'static str)> {
    let p = [
        [x, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    let faces = [[0u32, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]];
    let mut ascii_ply = String::from(
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n",
    );
    let mut obj = String::new();
    let mut stl_ascii = String::from("solid t\n");
    for q in p {
        ascii_ply += &format!("{:e} {} {}\n", q[0], q[1], q[2]);
        obj += &format!("v {:e} {} {}\n", q[0], q[1], q[2]);
    }
    let mut stl = vec![0u8; 80];
    stl.extend_from_slice(&4u32.to_le_bytes());
    for t in faces {
        ascii_ply += &format!("3 {} {} {}\n", t[0], t[1], t[2]);
        obj += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
        stl_ascii += "facet normal 0 0 1\nouter loop\n";
        stl.extend_from_slice(&[0u8; 12]);
        for v in t {
            let q = p[v as usize];
            stl_ascii += &format!("vertex {:e} {} {}\n", q[0], q[1], q[2]);
            for c in q {
                stl.extend_from_slice(&(c as f32).to_le_bytes());
            }
        }
        stl_ascii += "endloop\nendfacet\n";
        stl.extend_from_slice(&[0u8; 2]);
    }
    stl_ascii += "endsolid t\n";
    let binary_ply = |ty: &str| {
        let mut b = header(&format!(
            "element vertex 4\nproperty {ty} x\nproperty {ty} y\nproperty {ty} z\nelement face 4\nproperty list uchar int vertex_indices\n"
        ));
        for q in p {
            for c in q {
                match ty {
                    "float" => b.extend_from_slice(&(c as f32).to_le_bytes()),
                    _ => b.extend_from_slice(&c.to_le_bytes()),
                }
            }
        }
        for t in faces {
            b.push(3);
            for v in t {
                b.extend_from_slice(&(v as i32).to_le_bytes());
            }
        }
        b
    };
    vec![
        ("ascii ply", "ply", ascii_ply.into_bytes(), "vertex 0"),
        ("binary ply", "ply", binary_ply("float"), "vertex 0"),
        (
            "binary ply of doubles",
            "ply",
            binary_ply("double"),
            "vertex 0",
        ),
        ("binary stl", "stl", stl, "triangle 0 corner 0"),
        ("ascii stl", "stl", stl_ascii.into_bytes(), "line 4"),
        ("obj", "obj", obj.into_bytes(), "line 1"),
    ]
}

/// Finite coordinates near f32's limit overflow the first sum of two (a smoothing step, an
/// edge vector): every reader refuses coordinates beyond +-1e7 mm and names where they are,
/// and accepts them up to that bound.
#[test]
fn coordinates_beyond_ten_kilometres_are_refused() {
    let _guard = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    for x in [3.39e38, -2e7, 1.0000001e7] {
        for (name, ext, bytes, place) in tetrahedra_with_x(x) {
            let msg = expect_err(&bytes, ext, name);
            assert!(
                msg.contains(place) && msg.contains("beyond +-1e7 mm"),
                "{name}, x = {x}: {msg}"
            );
        }
    }
    for x in [9.99e6, -1e7] {
        for (name, ext, bytes, _) in tetrahedra_with_x(x) {
            let loaded = check(&bytes, ext).unwrap_or_else(|e| panic!("{name}, x = {x}: {e}"));
            assert_eq!(loaded.mesh.positions()[0][0], x as f32, "{name}");
        }
    }
    // Non-finite values keep their own message.
    for (name, ext, bytes, place) in tetrahedra_with_x(f64::INFINITY) {
        let msg = expect_err(&bytes, ext, name);
        assert!(
            msg.contains(place) && msg.contains("not a finite"),
            "{name}: {msg}"
        );
    }
}

#[test]
fn malformed_files_name_the_problem() {
    let _guard = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    warm_up();
    let cases: Vec<(&str, Vec<u8>, &str, &str)> = vec![
        ("empty", vec![], "ply", "empty"),
        ("header only", b"ply\nformat ascii 1.0\n".to_vec(), "ply", "end_header"),
        ("no format", b"ply\nelement vertex 0\nend_header\n".to_vec(), "ply", "format"),
        ("bad magic", b"plx\nformat ascii 1.0\nend_header\n".to_vec(), "ply", "magic"),
        ("unknown keyword", b"ply\nformat ascii 1.0\nelemnt vertex 1\nend_header\n".to_vec(), "ply", "line 3"),
        ("unknown type", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n".to_vec(), "ply", "float128"),
        ("duplicate element", b"ply\nformat ascii 1.0\nelement vertex 0\nelement vertex 0\nend_header\n".to_vec(), "ply", "twice"),
        ("no vertex element", b"ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n".to_vec(), "ply", "vertex"),
        ("missing z", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n".to_vec(), "ply", "\"z\""),
        ("float indices", b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nelement face 0\nproperty list uchar float vertex_indices\nend_header\n".to_vec(), "ply", "list of integers"),
        ("no vertices", b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n".to_vec(), "ply", "no vertices"),
        ("ascii too few values", b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2\n3 4 5\n6 7 8\n".to_vec(), "ply", "fewer values"),
        ("ascii too many values", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3 4\n".to_vec(), "ply", "more values"),
        ("ascii not a number", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 zwei 3\n".to_vec(), "ply", "line 8"),
        ("ascii uchar overflow", b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n300 0 1 2\n".to_vec(), "ply", "does not fit"),
        ("garbage", (0..200u8).map(|i| i.wrapping_mul(37)).collect(), "dat", "unknown mesh format"),
        ("stl lying count", { let mut b = vec![0u8; 84 + 50]; b[80] = 2; b }, "stl", "declares 2 triangles"),
        ("stl too short", b"abc".to_vec(), "stl", "too short"),
        ("stl ascii bad keyword", b"solid x\n facet normal 0 0 1\n outer loop\n vertex 0 0 0\n vortex 1 0 0\n".to_vec(), "stl", "line 5"),
        ("obj bad index", b"v 0 0 0\nv 1 0 0\nf 1 2 3\n".to_vec(), "obj", "line 3"),
        ("obj zero index", b"v 0 0 0\nv 1 0 0\nv 1 1 0\nf 0 1 2\n".to_vec(), "obj", "out of range"),
        ("obj nan", b"v 0 nan 0\n".to_vec(), "obj", "not a finite"),
    ];
    for (name, bytes, ext, needle) in cases {
        let msg = expect_err(&bytes, ext, name);
        assert!(
            msg.contains(needle),
            "{name}: {msg:?} does not mention {needle:?}"
        );
    }
}

#[test]
fn read_error_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tumor.ply");
    std::fs::write(&path, b"ply\nformat ascii 1.0\n").unwrap();
    let err = destair::io::read_mesh(&path, &ReadOptions::default()).unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("tumor.ply") && msg.contains("end_header"),
        "{msg}"
    );
    let missing =
        destair::io::read_mesh(&dir.path().join("nope.ply"), &ReadOptions::default()).unwrap_err();
    assert!(missing.to_string().contains("nope.ply"));
}

/// Applies one random mutation: byte flips, interesting values, splices, truncation.
fn mutate(rng: &mut fastrand::Rng, bytes: &mut Vec<u8>) {
    const INTERESTING: [&[u8]; 10] = [
        b"\xff\xff\xff\xff",
        b"\x00\x00\x00\x80",
        b"\x00\x00\xc0\x7f",
        b"\x7f",
        b"\x80",
        b"4294967296",
        b"-1",
        b"nan",
        b"\r\n",
        b"99999999999",
    ];
    if bytes.is_empty() {
        bytes.push(rng.u8(..));
        return;
    }
    let at = rng.usize(..bytes.len());
    match rng.u8(..6) {
        0 => bytes[at] ^= 1 << rng.u8(..8),
        1 => bytes[at] = rng.u8(..),
        2 => {
            let v = INTERESTING[rng.usize(..INTERESTING.len())];
            let end = (at + v.len()).min(bytes.len());
            bytes[at..end].copy_from_slice(&v[..end - at]);
        }
        3 => {
            let v = INTERESTING[rng.usize(..INTERESTING.len())];
            bytes.splice(at..at, v.iter().copied());
        }
        4 => {
            let len = rng.usize(..=(bytes.len() - at).min(16));
            bytes.drain(at..at + len);
        }
        _ => bytes.truncate(at),
    }
}

#[test]
fn thousands_of_random_mutations() {
    let _guard = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    warm_up();
    let mut rng = fastrand::Rng::with_seed(0xde57a1);
    let mut n_ok = 0;
    let mut n_err = 0;
    for (_, ext, valid) in valid_files() {
        for _ in 0..1500 {
            let mut bytes = valid.clone();
            for _ in 0..rng.usize(1..4) {
                mutate(&mut rng, &mut bytes);
            }
            match check(&bytes, ext) {
                Ok(_) => n_ok += 1,
                Err(_) => n_err += 1,
            }
        }
    }
    // Both outcomes occur, so the mutations reach deep into the decoders.
    assert!(n_ok > 500 && n_err > 2000, "ok {n_ok}, errors {n_err}");
}
