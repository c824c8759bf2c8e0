//! The cantilever under its own weight against the heavy elastica (docs/gravity.md): the tip's
//! drop and its shortening over the length, for loads `qL³/(EI)` from 0 to 8, from the
//! elastica (`validation::HeavyElastica`), from beam theory, and from Neo-Hookean tetrahedra
//! (`validation::SelfWeight`, 6 cells across); a table, and docs/heavy-elastica.svg.
//!
//!     cargo run --release -p voxcollide-sim --example heavy_elastica -- [SVG]
//!
//! About two minutes on 2 cores.

use std::error::Error;
use std::path::{Path, PathBuf};

use plotters::prelude::*;
use voxcollide_sim::validation::{HeavyElastica, SelfWeight};

fn main() -> Result<(), Box<dyn Error>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).ancestors().nth(2).unwrap_or(Path::new("."));
    let svg = std::env::args().nth(1).map_or_else(|| root.join("docs/heavy-elastica.svg"), PathBuf::from);
    let across = 6;
    let mut points = Vec::new();
    println!(
        "| qL³/(EI) | drop / L | elastica | beam theory | shortening / L | elastica | steps | residual |"
    );
    println!("| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |");
    for alpha in [1.0, 2.0, 4.0, 6.0, 8.0] {
        let c = SelfWeight { across, gravity: (alpha / 12_000.0) as f32, ..SelfWeight::standard() };
        let r = c.solve()?;
        let e = HeavyElastica::solve(alpha);
        let l = f64::from(c.length);
        let (drop, shortening) = (r.deflection / l, r.shortening / l);
        println!(
            "| {alpha} | {drop:.4} | {:.4} | {:.4} | {shortening:.4} | {:.4} | {} | {:.1e} |",
            e.drop,
            alpha / 8.0,
            1.0 - e.reach,
            r.steps,
            r.residual
        );
        points.push((alpha, drop, shortening));
    }
    plot(&points, across, &svg)?;
    println!("\nwrote {}", svg.display());
    Ok(())
}

fn plot(points: &[(f64, f64, f64)], across: u32, path: &Path) -> Result<(), Box<dyn Error>> {
    let mut text = String::new();
    {
        let area = SVGBackend::with_string(&mut text, (760, 520)).into_drawing_area();
        area.fill(&WHITE)?;
        let blue = RGBColor(31, 119, 180);
        let red = RGBColor(214, 39, 40);
        let mut chart = ChartBuilder::on(&area)
            .caption("Cantilever L/b = 10 under its own weight: the tip, over L", ("sans-serif", 20))
            .margin(16)
            .x_label_area_size(50)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..8.2, 0.0..1.0)?;
        chart
            .configure_mesh()
            .x_desc("load qL³/(EI)")
            .y_desc("tip drop / L, tip shortening / L")
            .label_style(("sans-serif", 15))
            .axis_desc_style(("sans-serif", 16))
            .draw()?;
        let curve: Vec<(f64, HeavyElastica)> =
            (0..=82).map(|k| 0.1 * f64::from(k)).map(|a| (a, HeavyElastica::solve(a))).collect();
        chart
            .draw_series(LineSeries::new([(0.0, 0.0), (8.0, 1.0)], BLACK.mix(0.4).stroke_width(1)))?
            .label("beam theory's drop, qL³/(8EI)")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLACK.mix(0.4)));
        chart
            .draw_series(LineSeries::new(curve.iter().map(|(a, e)| (*a, e.drop)), blue.stroke_width(2)))?
            .label("heavy elastica: drop")
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], blue.stroke_width(2)));
        chart
            .draw_series(LineSeries::new(
                curve.iter().map(|(a, e)| (*a, 1.0 - e.reach)),
                red.stroke_width(2),
            ))?
            .label("heavy elastica: shortening")
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], red.stroke_width(2)));
        chart
            .draw_series(points.iter().map(|&(a, d, _)| Circle::new((a, d), 6, blue.filled())))?
            .label(format!("tetrahedra, {across} across: drop"))
            .legend(move |(x, y)| Circle::new((x + 10, y), 5, blue.filled()));
        chart
            .draw_series(points.iter().map(|&(a, _, s)| Circle::new((a, s), 6, red.filled())))?
            .label(format!("tetrahedra, {across} across: shortening"))
            .legend(move |(x, y)| Circle::new((x + 10, y), 5, red.filled()));
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
