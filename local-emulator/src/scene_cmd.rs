//! `hort scene generate`.

use crate::cli::GenerateArgs;
use anyhow::{Context, Result};
use std::io::Write;

pub fn generate(args: GenerateArgs) -> Result<()> {
    hort_core::generate::check_triangle_count(args.triangles).map_err(anyhow::Error::msg)?;
    let file = std::fs::File::create(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let mut out = std::io::BufWriter::new(file);
    let summary = hort_core::generate::generate_scene(args.triangles, args.seed, &mut out)
        .and_then(|s| out.flush().map(|()| s))
        .with_context(|| format!("cannot write {}", args.out.display()))?;
    eprintln!(
        "wrote {} triangles, {} vertices -> {}",
        summary.triangles,
        summary.vertices,
        args.out.display()
    );
    Ok(())
}
