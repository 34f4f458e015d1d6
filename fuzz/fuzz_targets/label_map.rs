//! Any bytes as a label-map file (NIfTI, gzipped NIfTI, NRRD, Slicer's .seg.nrrd, a detached
//! .nhdr with a data file beside it): the header peek and reading must answer with a label map
//! or an error, never panic nor allocate beyond the declared sizes (run under an address-space
//! limit); a map that reads has its surfaces counted and, when small, extracted, and the count
//! must equal what the extraction makes.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&which, bytes)) = data.split_first() else {
        return;
    };
    let name = [
        "case.nii",
        "case.nii.gz",
        "case.nrrd",
        "case.seg.nrrd",
        "case.nhdr",
    ][which as usize % 5];
    let dir = std::env::temp_dir().join(format!("destair-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    // A data file beside a detached header, and one outside its folder it must never read.
    std::fs::write(dir.join("data.raw"), &bytes[bytes.len() / 2..]).unwrap();
    let _ = destair::volume::read_header(&path);
    let read = destair::volume::read_label_map(&path, destair::volume::grid::Space::Ras);
    let _ = std::fs::remove_file(&path);
    let Ok(map) = read else {
        return;
    };
    if let Some(data) = &map.data_file {
        assert!(data.starts_with(dir.canonicalize().unwrap()), "{data:?}");
    }
    for (index, layer) in map.layers.iter().enumerate() {
        if layer.voxels.len() > 200_000 {
            continue;
        }
        // Both connectivities, label by label as the layer's index and the label say.
        let connectivity: Vec<destair::extract::Connectivity> = (0..=layer.labels.len())
            .map(|l| {
                if (l + index) % 3 == 0 {
                    destair::extract::Connectivity::Faces
                } else {
                    destair::extract::Connectivity::Corners
                }
            })
            .collect();
        let size = destair::extract::surface_size(layer, &connectivity);
        if size.triangles > 2_000_000 {
            continue;
        }
        let interfaces = destair::extract::interfaces(layer, &connectivity);
        let made: u64 = destair::extract::label_surfaces(layer, &interfaces)
            .iter()
            .map(|s| s.mesh.n_triangles() as u64)
            .sum();
        assert_eq!(made, size.triangles);
    }
});
