//! Reading a mesh with destair as a library: load, build topology, print a few facts.
//!
//! Run with `cargo run --release --example inspect_mesh -- path/to/mesh.ply`.

use destair::io::{read_mesh, ReadOptions};
use destair::mesh::geometry::{area, signed_volume};
use destair::Topology;

fn main() -> anyhow::Result<()> {
    let Some(path) = std::env::args_os().nth(1) else {
        anyhow::bail!("usage: inspect_mesh MESH");
    };
    let loaded = read_mesh(path.as_ref(), &ReadOptions::default())?;
    let topology = Topology::build(&loaded.mesh);
    println!(
        "{} vertices, {} triangles, {} boundary loops, area {:.2} mm², volume {:.2} mm³",
        loaded.mesh.n_vertices(),
        loaded.mesh.n_triangles(),
        topology.boundary_loops().len(),
        area(&loaded.mesh),
        signed_volume(&loaded.mesh)
    );
    for warning in &loaded.warnings {
        println!("warning: {warning}");
    }
    Ok(())
}
