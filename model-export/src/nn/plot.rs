//! The loss curve (the paper's Figure 10) as an SVG.
use super::train::History;
use anyhow::{Result, anyhow};
use plotters::prelude::*;
use std::path::Path;

/// Draws training and validation RMS loss per epoch to an SVG file (written atomically).
pub fn loss_curve(h: &History, path: &Path) -> Result<()> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (800, 500)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
        let n = h.train.len().max(2);
        let ymax = h.train.iter().chain(&h.val).cloned().filter(|v| v.is_finite()).fold(0.0f64, f64::max).max(1e-6) * 1.05;
        let mut chart = ChartBuilder::on(&root)
            .caption(format!("Loss (RMS, normalised), lr {}", h.lr), ("sans-serif", 22))
            .margin(15)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(1f64..n as f64, 0f64..ymax)
            .map_err(|e| anyhow!("{e}"))?;
        chart.configure_mesh().x_desc("epoch").y_desc("RMS loss").draw().map_err(|e| anyhow!("{e}"))?;
        let series = |v: &Vec<f64>| v.iter().enumerate().map(|(k, y)| ((k + 1) as f64, *y)).collect::<Vec<_>>();
        chart
            .draw_series(LineSeries::new(series(&h.train), &BLUE))
            .map_err(|e| anyhow!("{e}"))?
            .label("training")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
        chart
            .draw_series(LineSeries::new(series(&h.val), &RED))
            .map_err(|e| anyhow!("{e}"))?
            .label("validation")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED));
        chart.configure_series_labels().border_style(BLACK).background_style(WHITE).draw().map_err(|e| anyhow!("{e}"))?;
        root.present().map_err(|e| anyhow!("{e}"))?;
    }
    crate::nn::write_atomic(path, svg.as_bytes())
}
