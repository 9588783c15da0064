//! PNG and SVG charts with [plotters](https://docs.rs/plotters): what the gaps of takes look
//! like, and how each gap-filling method does by gap length.
//!
//! * [`Chart::gap_lengths`]: histogram of gap lengths (in the gap-length bins of every locap
//!   metric, [`locap_core::gaps::LENGTH_BINS`]), the distribution the LocalMoCap occlusion
//!   augmentation draws from (section 3.3, Eq. 6).
//! * [`Chart::occlusion_rates`]: per marker, the fraction of frames it is missing (the
//!   paper's per-marker occlusion probability).
//! * [`Chart::fill_error`]: mean error against gap length, one line per method, from the
//!   data series a benchmark gives (`locap_eval`'s fill benchmark report converts itself).
//!
//! plotters is built without its default features (they pull in fontconfig, `image` and
//! chrono): text is drawn with `ab_glyph` from DejaVu Sans cut down to ASCII (10 kB,
//! `assets/DejaVuSans-ascii.ttf`, licence beside it), and PNGs are encoded with `png`.

use crate::ViewError;
use locap_core::GapStatistics;
use locap_core::gaps::ErrorByGapLength;
use plotters::coord::Shift;
use plotters::prelude::*;

const FONT: &[u8] = include_bytes!("../assets/DejaVuSans-ascii.ttf");

/// Line colours of the methods, in report order.
const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

/// Output format of a chart.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// PNG image (8-bit RGB).
    Png,
    /// SVG drawing.
    Svg,
}

impl Format {
    /// The format named by a file extension (`png`, `svg`, any case).
    pub fn from_extension(ext: &str) -> Option<Format> {
        match ext.to_ascii_lowercase().as_str() {
            "png" => Some(Format::Png),
            "svg" => Some(Format::Svg),
            _ => None,
        }
    }
}

/// One chart, ready to draw.
#[derive(Debug, Clone, PartialEq)]
pub enum Chart {
    /// Number of gaps per gap-length bin.
    GapLengths {
        /// Title.
        title: String,
        /// Bins: label (frames) and number of gaps.
        bins: Vec<(String, usize)>,
    },
    /// Fraction of frames each marker is missing.
    OcclusionRates {
        /// Title.
        title: String,
        /// Marker name and missing percentage.
        markers: Vec<(String, f64)>,
    },
    /// Mean error by gap length, one line per method.
    FillError {
        /// Title.
        title: String,
        /// Gap-length bucket labels (frames).
        buckets: Vec<String>,
        /// Method name and mean error in mm per bucket (`None` without samples).
        methods: Vec<(String, Vec<Option<f64>>)>,
    },
    /// One horizontal bar per item (e.g. a solver's error per joint).
    Bars {
        /// Title.
        title: String,
        /// Label of the value axis (with its unit).
        x_desc: String,
        /// Item name and value.
        items: Vec<(String, f64)>,
    },
    /// Training loss against step, one line per series (training, validation, ...).
    LossCurve {
        /// Title.
        title: String,
        /// Label of the loss axis (with its unit).
        y_desc: String,
        /// Series name and `(step, loss)` points in step order.
        series: Vec<(String, Vec<(f64, f64)>)>,
    },
}

impl Chart {
    /// Gap-length histogram pooled over `stats` (one per take), in the bins of
    /// [`locap_core::gaps::LENGTH_BINS`] (1-10, 11-30, ... frames) up to the longest gap, so it
    /// reads side by side with the error-by-gap-length charts.
    ///
    /// # Errors
    /// The takes have no gaps.
    pub fn gap_lengths(stats: &[GapStatistics], title: &str) -> Result<Chart, ViewError> {
        let mut pooled = Vec::new();
        for s in stats {
            locap_core::gaps::add_histogram(&mut pooled, &s.gap_length_histogram);
        }
        let counts = locap_core::gaps::binned(&pooled);
        let last =
            counts.iter().rposition(|n| *n > 0).ok_or_else(|| ViewError::Empty("the takes have no gaps".into()))?;
        let bins = locap_core::gaps::length_bin_labels().into_iter().zip(counts).take(last + 1).collect();
        Ok(Chart::GapLengths { title: title.to_string(), bins })
    }

    /// Percentage of frames each marker is missing, pooled over `stats` by marker name (in
    /// order of first appearance).
    ///
    /// # Errors
    /// The takes have no markers.
    pub fn occlusion_rates(stats: &[GapStatistics], title: &str) -> Result<Chart, ViewError> {
        let mut markers: Vec<(String, usize, usize)> = Vec::new();
        for s in stats {
            for m in &s.markers {
                match markers.iter_mut().find(|(name, _, _)| *name == m.name) {
                    Some(entry) => {
                        entry.1 += m.missing_frames;
                        entry.2 += m.total_frames;
                    }
                    None => markers.push((m.name.clone(), m.missing_frames, m.total_frames)),
                }
            }
        }
        if markers.is_empty() {
            return Err(ViewError::Empty("the takes have no markers".into()));
        }
        let markers = markers
            .into_iter()
            .map(|(name, missing, total)| (name, if total == 0 { 0.0 } else { 100.0 * missing as f64 / total as f64 }))
            .collect();
        Ok(Chart::OcclusionRates { title: title.to_string(), markers })
    }

    /// Mean error by gap length, one line per method: `methods` are a name and its
    /// `(bin label, mean error mm)` points, `None` where the bin has no samples. The x axis has
    /// every bin label in order of first appearance; a method without a bin has no point there.
    ///
    /// # Errors
    /// No methods or no bins.
    pub fn fill_error(methods: &[ErrorByGapLength], title: &str) -> Result<Chart, ViewError> {
        if methods.is_empty() {
            return Err(ViewError::Empty("no methods".into()));
        }
        let mut buckets: Vec<String> = Vec::new();
        for (_, points) in methods {
            for (label, _) in points {
                if !buckets.contains(label) {
                    buckets.push(label.clone());
                }
            }
        }
        if buckets.is_empty() {
            return Err(ViewError::Empty("no gap-length bins".into()));
        }
        let methods = methods
            .iter()
            .map(|(name, points)| {
                let errors = buckets
                    .iter()
                    .map(|b| points.iter().find(|(label, _)| label == b).and_then(|(_, mean)| *mean))
                    .collect();
                (name.clone(), errors)
            })
            .collect();
        Ok(Chart::FillError { title: title.to_string(), buckets, methods })
    }

    /// Loss curve of a training run: `series` are `(name, [(step, loss)])`.
    ///
    /// # Errors
    /// No series has a finite point.
    pub fn loss_curve(series: Vec<(String, Vec<(f64, f64)>)>, y_desc: &str, title: &str) -> Result<Chart, ViewError> {
        let series: Vec<_> = series
            .into_iter()
            .map(|(name, points)| (name, points.into_iter().filter(|(x, y)| x.is_finite() && y.is_finite()).collect()))
            .collect();
        if series.iter().all(|(_, p): &(String, Vec<(f64, f64)>)| p.is_empty()) {
            return Err(ViewError::Empty("the loss curve has no points".into()));
        }
        Ok(Chart::LossCurve { title: title.to_string(), y_desc: y_desc.to_string(), series })
    }

    /// Size in pixels that fits the chart's content.
    pub fn default_size(&self) -> (u32, u32) {
        match self {
            Chart::OcclusionRates { markers: items, .. } | Chart::Bars { items, .. } => {
                (800, 90 + 16 * items.len() as u32)
            }
            _ => (800, 480),
        }
    }

    /// Draws the chart as PNG or SVG bytes of `size` pixels.
    ///
    /// # Errors
    /// plotters fails to draw (e.g. a size too small for the labels) or the PNG encoder
    /// fails.
    pub fn render(&self, format: Format, size: (u32, u32)) -> Result<Vec<u8>, ViewError> {
        register_font()?;
        let (w, h) = size;
        if w < 100 || h < 80 {
            return Err(ViewError::Chart(format!("{w}x{h} pixels is too small for a chart")));
        }
        match format {
            Format::Svg => {
                let mut text = String::new();
                {
                    let root = SVGBackend::with_string(&mut text, size).into_drawing_area();
                    self.draw(&root)?;
                    root.present().map_err(chart_error)?;
                }
                Ok(text.into_bytes())
            }
            Format::Png => {
                let mut rgb = vec![0u8; w as usize * h as usize * 3];
                {
                    let root = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
                    self.draw(&root)?;
                    root.present().map_err(chart_error)?;
                }
                let mut out = Vec::new();
                let mut encoder = png::Encoder::new(&mut out, w, h);
                encoder.set_color(png::ColorType::Rgb);
                encoder.set_depth(png::BitDepth::Eight);
                let mut writer = encoder.write_header().map_err(|e| ViewError::Chart(e.to_string()))?;
                writer.write_image_data(&rgb).map_err(|e| ViewError::Chart(e.to_string()))?;
                writer.finish().map_err(|e| ViewError::Chart(e.to_string()))?;
                Ok(out)
            }
        }
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), ViewError> {
        root.fill(&WHITE).map_err(chart_error)?;
        match self {
            Chart::GapLengths { title, bins } => {
                let top = bins.iter().map(|(_, n)| *n).max().unwrap_or(1).max(1);
                let mut chart = ChartBuilder::on(root)
                    .caption(title, ("sans-serif", 20))
                    .margin(12)
                    .x_label_area_size(46)
                    .y_label_area_size(60)
                    .build_cartesian_2d(segments(bins.len()), 0..top + top / 10 + 1)
                    .map_err(chart_error)?;
                chart
                    .configure_mesh()
                    .disable_x_mesh()
                    .x_desc("gap length, frames")
                    .y_desc("gaps")
                    .light_line_style(TRANSPARENT)
                    .x_labels(bins.len())
                    .x_label_formatter(&|v| match v {
                        SegmentValue::CenterOf(i) => bins.get(*i).map(|b| b.0.clone()).unwrap_or_default(),
                        _ => String::new(),
                    })
                    .label_style(("sans-serif", 12))
                    .draw()
                    .map_err(chart_error)?;
                chart
                    .draw_series(bins.iter().enumerate().map(|(i, (_, n))| {
                        let mut bar = Rectangle::new(
                            [(SegmentValue::Exact(i), 0), (SegmentValue::Exact(i + 1), *n)],
                            PALETTE[0].filled(),
                        );
                        bar.set_margin(0, 0, 3, 3);
                        bar
                    }))
                    .map_err(chart_error)?;
            }
            Chart::OcclusionRates { title, markers } => bars(root, title, "frames missing, %", markers, PALETTE[3])?,
            Chart::Bars { title, x_desc, items } => bars(root, title, x_desc, items, PALETTE[0])?,
            Chart::FillError { title, buckets, methods } => {
                // Errors span three orders of magnitude (1-frame gaps vs 10-second gaps): log scale.
                let values = || methods.iter().flat_map(|(_, e)| e.iter().flatten().copied()).filter(|e| *e > 0.0);
                let top = values().fold(1.0, f64::max) * 1.5;
                let bottom = values().fold(top, f64::min).max(0.01) / 1.5;
                let mut chart = ChartBuilder::on(root)
                    .caption(title, ("sans-serif", 20))
                    .margin(12)
                    .x_label_area_size(46)
                    .y_label_area_size(60)
                    .build_cartesian_2d(segments(buckets.len()), (bottom..top).log_scale())
                    .map_err(chart_error)?;
                chart
                    .configure_mesh()
                    .x_desc("hidden gap length, frames")
                    .y_desc("mean error, mm (log scale)")
                    .light_line_style(TRANSPARENT)
                    .x_labels(buckets.len())
                    .x_label_formatter(&|v| match v {
                        SegmentValue::CenterOf(i) => buckets.get(*i).cloned().unwrap_or_default(),
                        _ => String::new(),
                    })
                    .label_style(("sans-serif", 12))
                    .draw()
                    .map_err(chart_error)?;
                for (k, (name, errors)) in methods.iter().enumerate() {
                    let colour = PALETTE[k % PALETTE.len()];
                    let points: Vec<(SegmentValue<usize>, f64)> = errors
                        .iter()
                        .enumerate()
                        .filter_map(|(i, e)| e.map(|e| (SegmentValue::CenterOf(i), e.max(bottom))))
                        .collect();
                    chart
                        .draw_series(LineSeries::new(points.clone(), colour.stroke_width(2)))
                        .map_err(chart_error)?
                        .label(name.as_str())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2)));
                    chart
                        .draw_series(points.into_iter().map(|p| Circle::new(p, 3, colour.filled())))
                        .map_err(chart_error)?;
                }
                draw_legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
            }
            Chart::LossCurve { title, y_desc, series } => {
                let points = || series.iter().flat_map(|(_, p)| p.iter().copied());
                let x_max = points().map(|p| p.0).fold(1.0, f64::max);
                let x_min = points().map(|p| p.0).fold(x_max, f64::min).min(x_max - 1.0);
                let y_max = points().map(|p| p.1).fold(f64::MIN, f64::max);
                let y_min = points().map(|p| p.1).fold(y_max, f64::min).min(0.0);
                let pad = ((y_max - y_min) * 0.05).max(1e-9);
                let mut chart = ChartBuilder::on(root)
                    .caption(title, ("sans-serif", 20))
                    .margin(12)
                    .x_label_area_size(46)
                    .y_label_area_size(60)
                    .build_cartesian_2d(x_min..x_max, y_min..y_max + pad)
                    .map_err(chart_error)?;
                chart
                    .configure_mesh()
                    .x_desc("step")
                    .y_desc(y_desc.as_str())
                    .light_line_style(TRANSPARENT)
                    .label_style(("sans-serif", 12))
                    .draw()
                    .map_err(chart_error)?;
                for (k, (name, points)) in series.iter().enumerate() {
                    let colour = PALETTE[k % PALETTE.len()];
                    chart
                        .draw_series(LineSeries::new(points.clone(), colour.stroke_width(2)))
                        .map_err(chart_error)?
                        .label(name.as_str())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2)));
                }
                draw_legend(&mut chart, SeriesLabelPosition::UpperRight)?;
            }
        }
        Ok(())
    }
}

/// Horizontal bars, the first item on top.
fn bars<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    x_desc: &str,
    markers: &[(String, f64)],
    colour: RGBColor,
) -> Result<(), ViewError> {
    let top = markers.iter().map(|(_, p)| *p).fold(0.0, f64::max).max(1.0) * 1.08;
    let mut chart = ChartBuilder::on(root)
        .caption(title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(110)
        .build_cartesian_2d(0.0..top, segments(markers.len()))
        .map_err(chart_error)?;
    chart
        .configure_mesh()
        .disable_y_mesh()
        .x_desc(x_desc)
        .light_line_style(TRANSPARENT)
        .y_labels(markers.len())
        // The y axis grows upwards; the first marker goes on top.
        .y_label_formatter(&|v| match v {
            SegmentValue::CenterOf(i) => {
                markers.get(markers.len() - 1 - i.min(&(markers.len() - 1))).map(|m| m.0.clone()).unwrap_or_default()
            }
            _ => String::new(),
        })
        .label_style(("sans-serif", 11))
        .draw()
        .map_err(chart_error)?;
    chart
        .draw_series(markers.iter().rev().enumerate().map(|(i, (_, p))| {
            let mut bar =
                Rectangle::new([(0.0, SegmentValue::Exact(i)), (*p, SegmentValue::Exact(i + 1))], colour.filled());
            bar.set_margin(2, 2, 0, 0);
            bar
        }))
        .map_err(chart_error)?;
    Ok(())
}

fn draw_legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
) -> Result<(), ViewError> {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.3))
        .label_font(("sans-serif", 12))
        .draw()
        .map_err(chart_error)
}

/// `n` categories, one segment each (a segmented `0..n` would add an empty last segment).
fn segments(n: usize) -> plotters::coord::ranged1d::SegmentedCoord<plotters::coord::types::RangedCoordusize> {
    (0..n.saturating_sub(1)).into_segmented()
}

fn chart_error(e: impl std::fmt::Display) -> ViewError {
    ViewError::Chart(e.to_string())
}

fn register_font() -> Result<(), ViewError> {
    static REGISTERED: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| plotters::style::register_font("sans-serif", FontStyle::Normal, FONT).is_ok());
    if ok { Ok(()) } else { Err(ViewError::Chart("the embedded font cannot be read".into())) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::{MarkerName, Take, Vec3};

    fn stats() -> GapStatistics {
        let markers = vec![MarkerName::parse("A"), MarkerName::parse("B")];
        let mut samples = vec![Some(Vec3::new(0.0, 0.0, 0.0)); 40 * 2];
        for f in [3, 10, 11, 12, 20, 21, 22, 23, 24] {
            samples[f * 2] = None;
        }
        GapStatistics::of_take(&Take::from_samples(markers, &samples, 100.0).unwrap())
    }

    #[test]
    fn gap_bins_are_the_metrics_bins() {
        let chart = Chart::gap_lengths(&[stats(), stats()], "gaps").unwrap();
        let Chart::GapLengths { bins, .. } = &chart else { panic!() };
        // Gaps of 1, 3 and 5 frames, twice: all in the first bin, the only one drawn.
        assert_eq!(bins, &[("1-10".into(), 6)]);
        let mut long = stats();
        long.gap_length_histogram.resize(50, 0);
        long.gap_length_histogram[45] = 2;
        let Chart::GapLengths { bins, .. } = Chart::gap_lengths(&[long], "gaps").unwrap() else { panic!() };
        assert_eq!(bins, [("1-10".into(), 3), ("11-30".into(), 0), ("31-60".into(), 2)]);
        let none = GapStatistics::of_take(
            &Take::from_samples(vec![MarkerName::parse("A")], &[Some(Vec3::zeros())], 1.0).unwrap(),
        );
        assert!(Chart::gap_lengths(&[none], "x").unwrap_err().to_string().contains("no gaps"));
    }

    #[test]
    fn occlusion_rates_pool_by_name() {
        let Chart::OcclusionRates { markers, .. } = Chart::occlusion_rates(&[stats(), stats()], "t").unwrap() else {
            panic!()
        };
        assert_eq!(markers, vec![("A".into(), 100.0 * 9.0 / 40.0), ("B".into(), 0.0)]);
    }

    #[test]
    fn charts_render_as_png_and_svg() {
        let chart = Chart::gap_lengths(&[stats()], "Gap lengths").unwrap();
        let png_bytes = chart.render(Format::Png, (640, 400)).unwrap();
        let decoder = png::Decoder::new(std::io::Cursor::new(&png_bytes));
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height), (640, 400));
        // Bars and text were drawn: plenty of non-white pixels, some of them the bar colour.
        let pixels: Vec<&[u8]> = buf[..info.buffer_size()].chunks(3).collect();
        assert!(pixels.iter().filter(|p| **p != [255, 255, 255]).count() > 2000);
        assert!(pixels.iter().any(|p| *p == [31, 119, 180]));
        let svg = String::from_utf8(
            Chart::occlusion_rates(&[stats()], "Rates").unwrap().render(Format::Svg, (600, 200)).unwrap(),
        )
        .unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("\nRates\n") && svg.contains("\nA\n"), "{svg}");
        assert!(chart.render(Format::Png, (10, 10)).unwrap_err().to_string().contains("too small"));
    }

    #[test]
    fn fill_error_lines_up_the_bins_of_every_method() {
        let methods = vec![
            ("edm".to_string(), vec![("1-10".to_string(), Some(1.5)), ("241+".to_string(), None)]),
            ("linear".to_string(), vec![("241+".to_string(), Some(90.0)), ("11-30".to_string(), Some(4.0))]),
        ];
        let chart = Chart::fill_error(&methods, "fill").unwrap();
        let Chart::FillError { buckets, methods, .. } = &chart else { panic!() };
        assert_eq!(buckets, &["1-10".to_string(), "241+".to_string(), "11-30".to_string()]);
        assert_eq!(methods[0], ("edm".to_string(), vec![Some(1.5), None, None]));
        assert_eq!(methods[1], ("linear".to_string(), vec![None, Some(90.0), Some(4.0)]));
        let svg = String::from_utf8(chart.render(Format::Svg, (800, 480)).unwrap()).unwrap();
        assert!(svg.contains("\nedm\n") && svg.contains("\nlinear\n"), "legend names the methods");
        assert!(Chart::fill_error(&[], "x").unwrap_err().to_string().contains("no methods"));
        assert!(Chart::fill_error(&[("a".into(), vec![])], "x").unwrap_err().to_string().contains("no gap-length"));
    }

    #[test]
    fn loss_curve_draws_every_series() {
        let train = (0..50).map(|i| (i as f64, 100.0 / (1.0 + i as f64))).collect();
        let valid = vec![(10.0, 20.0), (20.0, 9.0), (f64::NAN, 1.0)];
        let chart =
            Chart::loss_curve(vec![("training".into(), train), ("validation".into(), valid)], "loss, mm", "Loss")
                .unwrap();
        let Chart::LossCurve { series, .. } = &chart else { panic!() };
        assert_eq!(series[1].1.len(), 2, "the NaN point is dropped");
        let svg = String::from_utf8(chart.render(Format::Svg, (800, 480)).unwrap()).unwrap();
        assert!(svg.contains("\ntraining\n") && svg.contains("\nvalidation\n") && svg.contains("<polyline"), "{svg}");
        assert!(Chart::loss_curve(vec![("x".into(), vec![])], "l", "t").unwrap_err().to_string().contains("no points"));
    }

    #[test]
    fn bars_name_their_axis() {
        let chart = Chart::Bars {
            title: "JPE per joint".into(),
            x_desc: "JPE, mm".into(),
            items: vec![("root".into(), 12.5), ("head".into(), 30.0)],
        };
        assert_eq!(chart.default_size(), (800, 90 + 32));
        let svg = String::from_utf8(chart.render(Format::Svg, chart.default_size()).unwrap()).unwrap();
        assert!(svg.contains("\nJPE, mm\n") && svg.contains("\nhead\n") && !svg.contains("missing"), "{svg}");
    }
}
