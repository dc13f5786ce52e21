//! The loss curve (the paper's Figure 10) as an SVG.
use super::train::History;
use anyhow::{Result, anyhow};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use std::path::Path;

/// Draws training and validation RMS loss per epoch to an SVG file (written atomically).
pub fn loss_curve(h: &History, path: &Path) -> Result<()> {
    crate::write_atomic(path, loss_curve_svg(h)?.as_bytes())
}

/// The loss curve of [`loss_curve`] as SVG text.
pub fn loss_curve_svg(h: &History) -> Result<String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (800, 500)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
        let n = h.train.len().max(2);
        let ymax = h
            .train
            .iter()
            .chain(&h.val)
            .cloned()
            .filter(|v| v.is_finite())
            .fold(0.0f64, f64::max)
            .max(1e-6)
            * 1.05;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!("Loss (RMS, normalised), lr {}", h.lr),
                ("sans-serif", 22),
            )
            .margin(15)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(1f64..n as f64, 0f64..ymax)
            .map_err(|e| anyhow!("{e}"))?;
        chart
            .configure_mesh()
            .x_desc("epoch")
            .y_desc("RMS loss")
            .draw()
            .map_err(|e| anyhow!("{e}"))?;
        let series = |v: &Vec<f64>| {
            v.iter()
                .enumerate()
                .map(|(k, y)| ((k + 1) as f64, *y))
                .collect::<Vec<_>>()
        };
        draw_lines(
            &mut chart,
            [
                (series(&h.train), BLUE, "training"),
                (series(&h.val), RED, "validation"),
            ],
        )?;
        root.present().map_err(|e| anyhow!("{e}"))?;
    }
    Ok(svg)
}

/// The paper's Figures 12 and 13: per output, the measured torque, the prediction and
/// the error over a streamed sequence, before compensation (the identified model alone)
/// and after (the network, streamed through the firmware f32 step): the file names
/// (`fig12_before.svg`, `fig13_after.svg`) and their SVG text, for the caller to write
/// with its other outputs.
pub fn compensation_figures(
    m: &crate::LstmModel,
    seq: &crate::data::Sequence,
) -> Result<Vec<(&'static str, String)>> {
    let pred = m.stream(&seq.inputs)?;
    let mut figures = Vec::new();
    let dt_s = 1.0 / 100.0;
    let column = |k: usize, f: &dyn Fn(usize) -> f32| -> Vec<(f64, f64)> {
        (0..seq.len())
            .map(|t| (t as f64 * dt_s, (f(t) + seq.offset[t][k]) as f64))
            .collect()
    };
    for (file, title, after) in [
        (
            "fig12_before.svg",
            "Before compensation: identified model",
            false,
        ),
        ("fig13_after.svg", "After compensation: model + LSTM", true),
    ] {
        let outputs = m.dims.output;
        let mut svg = String::new();
        {
            let root =
                SVGBackend::with_string(&mut svg, (1000, 300 * outputs as u32)).into_drawing_area();
            root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
            for (k, area) in root.split_evenly((outputs, 1)).iter().enumerate() {
                let measured = column(k, &|t| seq.targets[t][k]);
                let predicted = if after {
                    column(k, &|t| pred[t][k])
                } else {
                    column(k, &|t| seq.model_only[t][k])
                };
                let error: Vec<(f64, f64)> = measured
                    .iter()
                    .zip(&predicted)
                    .map(|(a, b)| (a.0, a.1 - b.1))
                    .collect();
                let (lo, hi) = measured
                    .iter()
                    .chain(&predicted)
                    .chain(&error)
                    .map(|p| p.1)
                    .filter(|v| v.is_finite())
                    .fold((0.0f64, 0.0f64), |(lo, hi), v| (lo.min(v), hi.max(v)));
                let pad = 0.05 * (hi - lo).max(1e-6);
                let t_end = (seq.len().max(2) - 1) as f64 * dt_s;
                let mut chart = ChartBuilder::on(area)
                    .caption(
                        format!("{title}: {}", m.output_names[k]),
                        ("sans-serif", 18),
                    )
                    .margin(10)
                    .x_label_area_size(35)
                    .y_label_area_size(55)
                    .build_cartesian_2d(0f64..t_end, (lo - pad)..(hi + pad))
                    .map_err(|e| anyhow!("{e}"))?;
                chart
                    .configure_mesh()
                    .x_desc("t [s]")
                    .y_desc("torque [N m]")
                    .draw()
                    .map_err(|e| anyhow!("{e}"))?;
                draw_lines(
                    &mut chart,
                    [
                        (measured, BLACK, "measured"),
                        (predicted, BLUE, "predicted"),
                        (error, RED, "error"),
                    ],
                )?;
            }
            root.present().map_err(|e| anyhow!("{e}"))?;
        }
        figures.push((file, svg));
    }
    Ok(figures)
}

/// Draws each `(points, colour, label)` as a line with a legend entry, then the legend.
fn draw_lines<'a, 'b: 'a>(
    chart: &mut ChartContext<'a, SVGBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    lines: impl IntoIterator<Item = (Vec<(f64, f64)>, RGBColor, &'static str)>,
) -> Result<()> {
    for (data, colour, label) in lines {
        chart
            .draw_series(LineSeries::new(data, &colour))
            .map_err(|e| anyhow!("{e}"))?
            .label(label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
    }
    chart
        .configure_series_labels()
        .border_style(BLACK)
        .background_style(WHITE)
        .draw()
        .map_err(|e| anyhow!("{e}"))?;
    Ok(())
}
