//! Any bytes as a label-map file (NIfTI, gzipped NIfTI, NRRD, Slicer's .seg.nrrd): reading
//! must answer with a label map or an error, never panic; a small map that reads has its
//! surfaces extracted.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&which, bytes)) = data.split_first() else {
        return;
    };
    let name = ["case.nii", "case.nii.gz", "case.nrrd", "case.seg.nrrd"][which as usize % 4];
    let dir = std::env::temp_dir().join(format!("destair-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    let read = destair::volume::read_label_map(&path, destair::volume::grid::Space::Ras);
    let _ = std::fs::remove_file(&path);
    let Ok(map) = read else {
        return;
    };
    for layer in &map.layers {
        if layer.voxels.len() > 200_000 {
            continue;
        }
        let interfaces = destair::extract::interfaces(layer);
        let _ = destair::extract::label_surfaces(layer, &interfaces);
    }
});
