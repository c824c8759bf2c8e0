//! The finite-element checks of tests/validation.rs (`voxcollide_sim::validation`), run once
//! with more points: their tables, and docs/validation.svg.
//!
//!     cargo run --release -p voxcollide-sim --example validation -- [SVG] [--fine]
//!
//! `--fine` adds a cantilever 16 cells across (46,000 vertices: minutes on 2 cores).

use std::error::Error;
use std::path::{Path, PathBuf};

use plotters::prelude::*;
use voxcollide_sim::validation::{Cantilever, CantileverResult, LargeStretch, LargeStretchResult};

fn main() -> Result<(), Box<dyn Error>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).ancestors().nth(2).unwrap_or(Path::new("."));
    let fine = std::env::args().any(|a| a == "--fine");
    let svg = std::env::args()
        .skip(1)
        .find(|a| !a.starts_with("--"))
        .map_or_else(|| root.join("docs/validation.svg"), PathBuf::from);

    let mut beams = Vec::new();
    println!("| cells across | vertices | steps | residual | tip load / beam theory | tip moment / F·L |");
    println!("| ---: | ---: | ---: | ---: | ---: | ---: |");
    for across in [2, 4, 8].into_iter().chain(fine.then_some(16)) {
        let c = Cantilever { across, ..Cantilever::standard() };
        let r = c.solve()?;
        println!(
            "| {across} | {} | {} | {:.1e} | {:.4} | {:.4} |",
            r.vertices,
            r.steps,
            r.residual,
            r.load / r.theory,
            r.moment / (r.load * f64::from(c.length))
        );
        beams.push((c, r));
    }

    let mut bars = Vec::new();
    println!("\n| ν | stretch (middle) | lateral | closed form | nominal stress | closed form | residual |");
    println!("| ---: | ---: | ---: | ---: | ---: | ---: | ---: |");
    for nu in [0.3, 0.45, 0.49] {
        for stretch in [1.1, 1.2, 1.3, 1.4, 1.5, 1.6, 1.7, 1.8] {
            let s = LargeStretch { nu, stretch, ..LargeStretch::standard() };
            let r = s.solve()?;
            let (lateral, stress) = s.closed_form(r.stretch);
            println!(
                "| {nu} | {:.4} | {:.4} | {lateral:.4} | {:.4} | {stress:.4} | {:.1e} |",
                r.stretch, r.lateral, r.stress, r.residual
            );
            bars.push((s, r));
        }
    }
    plot(&beams, &bars, &svg)?;
    println!("\nwrote {}", svg.display());
    Ok(())
}

fn plot(
    beams: &[(Cantilever, CantileverResult)],
    bars: &[(LargeStretch, LargeStretchResult)],
    path: &Path,
) -> Result<(), Box<dyn Error>> {
    let mut text = String::new();
    {
        let area = SVGBackend::with_string(&mut text, (1200, 520)).into_drawing_area();
        area.fill(&WHITE)?;
        let (left, right) = area.split_horizontally(560);
        let blue = RGBColor(31, 119, 180);
        let red = RGBColor(214, 39, 40);
        let green = RGBColor(44, 160, 44);

        // The cantilever: tip load over beam theory's against (spacing / width)².
        let h2 = |c: &Cantilever| (1.0 / f64::from(c.across)).powi(2);
        let mut chart = ChartBuilder::on(&left)
            .caption("Cantilever L/b = 10, ν = 0.3: tip load / beam theory", ("sans-serif", 20))
            .margin(16)
            .x_label_area_size(50)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..0.27, 0.9..2.1)?;
        chart
            .configure_mesh()
            .x_desc("(spacing / width)²")
            .y_desc("load / Timoshenko beam")
            .label_style(("sans-serif", 15))
            .axis_desc_style(("sans-serif", 16))
            .draw()?;
        chart
            .draw_series(LineSeries::new([(0.0, 1.0), (0.27, 1.0)], BLACK.mix(0.5).stroke_width(1)))?
            .label("beam theory")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLACK.mix(0.5)));
        chart
            .draw_series(LineSeries::new([(0.0, 0.95), (0.27, 0.95)], BLACK.mix(0.2)))?
            .label("± 5 %")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLACK.mix(0.2)));
        chart.draw_series(LineSeries::new([(0.0, 1.05), (0.27, 1.05)], BLACK.mix(0.2)))?;
        chart
            .draw_series(beams.iter().map(|(c, r)| Circle::new((h2(c), r.load / r.theory), 6, red.filled())))?
            .label("tetrahedra, 2 / 4 / 8 across")
            .legend(move |(x, y)| Circle::new((x + 10, y), 5, red.filled()));
        // The second-order line through the two finest, to h = 0 (Richardson).
        if let [.., (c1, r1), (c2, r2)] = beams {
            let (x1, y1, x2, y2) = (h2(c1), r1.load / r1.theory, h2(c2), r2.load / r2.theory);
            let slope = (y1 - y2) / (x1 - x2);
            let at0 = y2 - slope * x2;
            chart
                .draw_series(DashedLineSeries::new([(0.0, at0), (x1, y1)], 6, 4, blue.stroke_width(2)))?
                .label(format!("second order, to h → 0: {at0:.3}"))
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], blue.stroke_width(2)));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .label_font(("sans-serif", 15))
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK.mix(0.4))
            .draw()?;

        // The bar: nominal stress against the middle's stretch, and the closed form.
        let at_two = |nu: f64| LargeStretch { nu, ..LargeStretch::standard() }.closed_form(2.0).1;
        let top = bars.iter().map(|(s, r)| r.stress.max(at_two(s.nu))).fold(0.0, f64::max) * 1.1;
        let mut chart = ChartBuilder::on(&right)
            .caption("Bar stretched up to 80 %: nominal stress (E = 1)", ("sans-serif", 20))
            .margin(16)
            .x_label_area_size(50)
            .y_label_area_size(60)
            .build_cartesian_2d(1.0..2.0, 0.0..top)?;
        chart
            .configure_mesh()
            .x_desc("axial stretch of the middle")
            .y_desc("axial load / area at rest")
            .label_style(("sans-serif", 15))
            .axis_desc_style(("sans-serif", 16))
            .draw()?;
        for (nu, colour) in [(0.3, blue), (0.45, green), (0.49, red)] {
            let s = LargeStretch { nu, ..LargeStretch::standard() };
            let curve = (0..=100).map(|k| {
                let l = 1.0 + 0.01 * f64::from(k);
                (l, s.closed_form(l).1)
            });
            chart
                .draw_series(LineSeries::new(curve, colour.stroke_width(2)))?
                .label(format!("closed form, ν = {nu}"))
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], colour.stroke_width(2)));
            chart.draw_series(
                bars.iter()
                    .filter(|(b, _)| b.nu == nu)
                    .map(|(_, r)| Cross::new((r.stretch, r.stress), 6, colour.stroke_width(2))),
            )?;
        }
        chart
            .draw_series(std::iter::empty::<Cross<(f64, f64), i32>>())?
            .label("tetrahedra (crosses)")
            .legend(|(x, y)| Cross::new((x + 10, y), 5, BLACK.stroke_width(2)));
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .label_font(("sans-serif", 15))
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK.mix(0.4))
            .draw()?;
        area.present()?;
    }
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    std::fs::write(path, text)?;
    Ok(())
}
