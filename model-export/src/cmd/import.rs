//! `model-export import`: a PyTorch (safetensors or ONNX) network into our format.
use anyhow::{Result, bail};
use clap::Args;
use compnet::io;
use std::path::PathBuf;

/// `import` options.
#[derive(Debug, Args)]
pub struct ImportArgs {
    /// Safetensors written from PyTorch, or an ONNX model (`.onnx`) exported from it.
    #[arg(long = "network", alias = "torch", value_name = "FILE")]
    pub network: PathBuf,
    /// Our network file to write (safetensors).
    #[arg(long, short)]
    pub out: PathBuf,
    /// Reference CSV (columns `x0..`, `y0..`: raw inputs and PyTorch's outputs per step);
    /// the firmware step must match it to `--tolerance` relative.
    #[arg(long)]
    pub reference: Option<PathBuf>,
    /// Relative tolerance for `--reference` (of the outputs' RMS).
    #[arg(long, default_value_t = 1e-5)]
    pub tolerance: f64,
    /// The activation after the input layer, for files without `input_activation`
    /// metadata (`tanh`, or `linear` for a plain `nn.Linear`); it must agree with the
    /// metadata where there is some.
    #[arg(long, value_parser = ["tanh", "linear"])]
    pub input_activation: Option<String>,
}

/// Runs `import`.
pub fn run(a: ImportArgs) -> Result<()> {
    let model = if compnet::onnx::is_onnx(&a.network) {
        // The graph says which activation follows the input layer.
        if let Some(act) = &a.input_activation {
            bail!(
                "{}: --input-activation {act} is for safetensors files; an ONNX graph names its own",
                a.network.display()
            );
        }
        compnet::onnx::read_onnx_model(&a.network)?
    } else {
        io::read_model_with(&a.network, a.input_activation.as_deref())?
    };
    println!(
        "{}: {:?}, preset `{}`",
        a.network.display(),
        model.dims,
        model.preset
    );
    if let Some(r) = &a.reference {
        let err = io::check_reference(&model, r)?;
        println!(
            "firmware f32 step vs {}: max error {err:.3e} of the output RMS",
            r.display()
        );
        if err > a.tolerance {
            bail!(
                "{}: the imported model differs from the reference by {err:.3e} > {}",
                r.display(),
                a.tolerance
            );
        }
    }
    io::write_model(&model, &a.out)?;
    println!("wrote {}", a.out.display());
    Ok(())
}
