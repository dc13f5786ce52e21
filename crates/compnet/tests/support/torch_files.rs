//! Writes safetensors files the way a PyTorch script does (a model's tensors, extra
//! tensors, metadata), shared by the importer's tests and the command line's
//! (`#[path]`-included, one source).
#![allow(dead_code)]

use compnet::LstmModel;
use std::path::{Path, PathBuf};

/// Writes `m`'s tensors (plus `extra`) as safetensors with `metadata`, as a PyTorch script
/// would; returns the path.
pub fn torch_style_file(
    dir: &Path,
    m: &LstmModel,
    extra: &[(&str, Vec<usize>, Vec<f32>)],
    metadata: &[(&str, &str)],
) -> PathBuf {
    use safetensors::{Dtype, tensor::TensorView};
    let d = m.dims;
    let shape = |n: &str| -> Vec<usize> {
        match n {
            "input.weight" => vec![d.embed, d.input],
            "input.bias" => vec![d.embed],
            "lstm.weight_ih_l0" => vec![4 * d.hidden, d.embed],
            "lstm.weight_hh_l0" => vec![4 * d.hidden, d.hidden],
            "lstm.bias_ih_l0" | "lstm.bias_hh_l0" => vec![4 * d.hidden],
            "output.weight" => vec![d.output, d.hidden],
            "output.bias" | "norm.output_mean" | "norm.output_std" => vec![d.output],
            _ => vec![d.input],
        }
    };
    let mut tensors: Vec<(String, Vec<usize>, Vec<u8>)> = m
        .tensors()
        .iter()
        .map(|(n, v)| {
            (
                n.to_string(),
                shape(n),
                v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            )
        })
        .collect();
    for (n, s, v) in extra {
        tensors.push((
            n.to_string(),
            s.clone(),
            v.iter().flat_map(|x| x.to_le_bytes()).collect(),
        ));
    }
    let views: Vec<(String, TensorView)> = tensors
        .iter()
        .map(|(n, s, b)| {
            (
                n.clone(),
                TensorView::new(Dtype::F32, s.clone(), b).unwrap(),
            )
        })
        .collect();
    let meta: std::collections::HashMap<String, String> = metadata
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    let bytes = safetensors::serialize(views, Some(meta)).unwrap();
    let path = dir.join("torch.safetensors");
    std::fs::write(&path, bytes).unwrap();
    path
}
