//! Line charts as SVG text with plotters, for pages that embed them inline (`compare`'s
//! report). The text is SVG `<text>`: the browser draws it, so no font file is needed.

use plotters::prelude::*;
use voxcollide::Error;

/// One curve: its legend label and its points, in any order of x (drawn as given).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Series {
    /// The legend's label.
    pub label: String,
    /// The points.
    pub points: Vec<(f64, f64)>,
}

/// What a chart shows: its title, its axes' descriptions, its curves and where its legend goes.
#[derive(Clone, Debug)]
pub struct Chart<'a> {
    /// The caption above the plot.
    pub title: &'a str,
    /// The x axis's description (with its unit).
    pub x: &'a str,
    /// The y axis's description (with its unit).
    pub y: &'a str,
    /// The curves, each in its own colour (matplotlib's ten, then plotters' palette).
    pub series: &'a [Series],
    /// The legend's corner: where the curves leave room.
    pub legend: SeriesLabelPosition,
}

/// The colour of curve `k`: the ten of matplotlib's `tab10` first.
pub fn colour(k: usize) -> RGBColor {
    const TAB10: [(u8, u8, u8); 10] = [
        (31, 119, 180),
        (255, 127, 14),
        (44, 160, 44),
        (214, 39, 40),
        (148, 103, 189),
        (140, 86, 75),
        (227, 119, 194),
        (127, 127, 127),
        (188, 189, 34),
        (23, 190, 207),
    ];
    match TAB10.get(k) {
        Some(&(r, g, b)) => RGBColor(r, g, b),
        None => {
            let (r, g, b) = Palette99::pick(k).rgb();
            RGBColor(r, g, b)
        }
    }
}

/// `chart` as an SVG document `width` × `height` pixels. The axes span the points (y from 0
/// when every y is at least 0), a little wider when they are all one value; non-finite points
/// are left out.
///
/// # Errors
/// [`Error::Invalid`] when plotters cannot draw it.
pub fn line_chart_svg(chart: &Chart<'_>, width: u32, height: u32) -> Result<String, Error> {
    let finite = |p: &&(f64, f64)| p.0.is_finite() && p.1.is_finite();
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in chart.series.iter().flat_map(|s| s.points.iter()).filter(finite) {
        (x0, x1, y0, y1) = (x0.min(p.0), x1.max(p.0), y0.min(p.1), y1.max(p.1));
    }
    if x0 > x1 {
        (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
    }
    if y0 >= 0.0 {
        y0 = 0.0;
    }
    let pad = |lo: f64, hi: f64| if hi > lo { (lo, hi + 0.05 * (hi - lo)) } else { (lo - 0.5, hi + 0.5) };
    let ((x0, x1), (y0, mut y1)) = (if x1 > x0 { (x0, x1) } else { pad(x0, x1) }, pad(y0, y1));
    // A legend along the top gets room of its own above the curves, so that it covers none.
    let on_top = matches!(
        chart.legend,
        SeriesLabelPosition::UpperLeft | SeriesLabelPosition::UpperMiddle | SeriesLabelPosition::UpperRight
    );
    if on_top && !chart.series.is_empty() {
        let legend_px = LEGEND_LINE_PX * chart.series.len() as f64 + 16.0;
        let plot_px = (f64::from(height) - 100.0).max(2.0 * legend_px);
        y1 += (y1 - y0) * legend_px / (plot_px - legend_px);
    }
    let mut text = String::new();
    draw(&mut text, chart, (width, height), (x0..x1, y0..y1)).map_err(|e| Error::Invalid {
        what: "chart",
        value: chart.title.to_string(),
        rule: format!("plotters could not draw it: {e}"),
    })?;
    Ok(text)
}

type Ranges = (std::ops::Range<f64>, std::ops::Range<f64>);

/// A legend line's height in pixels, at its 13-pixel font.
const LEGEND_LINE_PX: f64 = 20.0;

fn draw(
    text: &mut String,
    chart: &Chart<'_>,
    size: (u32, u32),
    (xs, ys): Ranges,
) -> Result<(), Box<dyn std::error::Error>> {
    let area = SVGBackend::with_string(text, size).into_drawing_area();
    area.fill(&WHITE)?;
    let mut c = ChartBuilder::on(&area)
        .caption(chart.title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(44)
        .y_label_area_size(60)
        .build_cartesian_2d(xs, ys)?;
    c.configure_mesh()
        .x_desc(chart.x)
        .y_desc(chart.y)
        .label_style(("sans-serif", 13))
        .axis_desc_style(("sans-serif", 14))
        .light_line_style(BLACK.mix(0.06))
        .max_light_lines(1)
        .draw()?;
    for (k, s) in chart.series.iter().enumerate() {
        let style = colour(k).stroke_width(2);
        let points = s.points.iter().copied().filter(|p| p.0.is_finite() && p.1.is_finite());
        c.draw_series(LineSeries::new(points, style))?
            .label(s.label.as_str())
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 18, y)], style));
    }
    if !chart.series.is_empty() {
        c.configure_series_labels()
            .position(chart.legend.clone())
            .label_font(("sans-serif", 13))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK.mix(0.3))
            .draw()?;
    }
    area.present()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_each_curve_with_its_label_and_the_axes() {
        let series = [
            Series { label: "a & <b>".into(), points: vec![(0.0, 0.0), (1.0, 2.0), (2.0, 1.0)] },
            Series { label: "flat".into(), points: vec![(0.0, 1.0), (2.0, 1.0), (f64::NAN, 3.0)] },
        ];
        let chart = Chart {
            title: "lift",
            x: "x (mm)",
            y: "lift (mm)",
            series: &series,
            legend: SeriesLabelPosition::UpperRight,
        };
        let svg = line_chart_svg(&chart, 400, 300).unwrap();
        assert!(svg.starts_with("<svg"), "{svg:.80}");
        // plotters writes each text on a line of its own.
        for text in ["lift", "x (mm)", "lift (mm)"] {
            assert!(svg.contains(&format!("\n{text}\n")), "{text} is missing");
        }
        // The label is escaped, and both curves are drawn in their colours.
        assert!(svg.contains("a &amp; &lt;b&gt;"), "the label is not escaped");
        // Each curve and its legend's line, in its colour; the NaN point is left out.
        for colour in ["#1F77B4", "#FF7F0E"] {
            let lines =
                svg.matches(&format!("<polyline fill=\"none\" opacity=\"1\" stroke=\"{colour}\"")).count();
            assert_eq!(lines, 2, "{colour}");
        }
        assert!(!svg.contains("NaN"));
    }

    #[test]
    fn one_point_and_no_points_still_draw() {
        let one = [Series { label: "one".into(), points: vec![(3.0, 3.0)] }];
        for series in [&one[..], &[]] {
            let chart = Chart { title: "t", x: "x", y: "y", series, legend: SeriesLabelPosition::LowerRight };
            assert!(line_chart_svg(&chart, 300, 200).unwrap().contains("</svg>"));
        }
    }
}
