//! Reconstruction, simplification and fairing of the unsupported surface on a cloud, written
//! as PLY meshes for `benches/peers/mesh_figures.py`:
//! `cargo run --release -p sl-mesh --example fair_gap -- CLOUD.ply OUT_DIR [RATIO] [DEPTH] [CURVATURE_STEPS]`
//! (with `NO_FAIR_RIM` set in the environment, `FairConfig::project_rim` off).

use std::path::PathBuf;
use std::time::Instant;

use sl_mesh::{
    FairConfig, PoissonConfig, SimplifyConfig, fair_unsupported, poisson_reconstruct, simplify,
    write_ply_mesh,
};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let cloud = sl_cloud::read_ply(&PathBuf::from(&args[1]))?;
    let out = PathBuf::from(&args[2]);
    std::fs::create_dir_all(&out)?;
    let ratio: f64 = args.get(3).map_or(Ok(0.1), |s| s.parse())?;
    let depth: u32 = args.get(4).map_or(Ok(9), |s| s.parse())?;
    let curvature: usize = args
        .get(5)
        .map_or(Ok(FairConfig::default().curvature_iterations), |s| {
            s.parse()
        })?;
    let t = Instant::now();
    let mut surface = poisson_reconstruct(
        &cloud,
        &PoissonConfig {
            depth,
            ..PoissonConfig::default()
        },
    )?;
    println!("reconstruct {:.0} ms", t.elapsed().as_secs_f64() * 1e3);
    let t = Instant::now();
    let s = simplify(
        &mut surface.mesh,
        &surface.densities,
        &SimplifyConfig::default(),
    )?;
    println!(
        "simplify {:.0} ms: {} vertices",
        t.elapsed().as_secs_f64() * 1e3,
        s.vertices_after
    );
    write_ply_mesh(&out.join("simplified.ply"), &surface.mesh)?;
    let t = Instant::now();
    let f = fair_unsupported(
        &mut surface.mesh,
        &s.densities,
        &FairConfig {
            support_ratio: ratio,
            curvature_iterations: curvature,
            project_rim: std::env::var_os("NO_FAIR_RIM").is_none(),
        },
    )?;
    println!("fair {:.1} ms: {f:?}", t.elapsed().as_secs_f64() * 1e3);
    write_ply_mesh(&out.join("faired.ply"), &surface.mesh)?;
    let topo = sl_mesh::check_topology(&surface.mesh);
    println!("watertight manifold: {}", topo.is_watertight_manifold());
    Ok(())
}
