//! The Hertz indentation of tests/hertz.rs, run once: the measured curve as CSV and its plot.
//!
//!     cargo run --release -p voxcollide-sim --example hertz -- [CSV [SVG]]
//!         [--history CSV] [--set key=value]…
//!
//! CSV defaults to out/hertz.csv and SVG to docs/hertz.svg, under the workspace root. The
//! plot is an SVG whose text the viewer draws, so no font file is needed. `--set` changes the set-up
//! (thickness, width, spacing, radius, ball_spacing, damping, magnitude (N or auto), ramp,
//! hold, window, depths (fractions of T, comma-separated), stiffening, model (springs or
//! neo-hookean), poisson, young_kpa); `--history` writes
//! the force against time.

#[path = "../tests/hertz.rs"]
mod hertz;

use std::error::Error;
use std::path::{Path, PathBuf};

use hertz::{Curve, Setup, bonded_layer, measure, summary, table};
use plotters::prelude::*;

fn main() -> Result<(), Box<dyn Error>> {
    // The workspace root, two folders above this crate's.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).ancestors().nth(2).unwrap_or(Path::new("."));
    let mut setup = Setup::standard();
    let (mut paths, mut history) = (Vec::new(), None);
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let mut value = || args.next().ok_or_else(|| format!("{arg} needs a value"));
        match arg.as_str() {
            "--history" => history = Some(PathBuf::from(value()?)),
            "--set" => set(&mut setup, &value()?)?,
            _ => paths.push(PathBuf::from(arg)),
        }
    }
    let csv = paths.first().cloned().unwrap_or_else(|| root.join("out/hertz.csv"));
    let svg = paths.get(1).cloned().unwrap_or_else(|| root.join("docs/hertz.svg"));

    let curve = measure(&setup)?;
    println!("{}\n\n{}", summary(&curve), table(&curve));
    write(&csv, &samples_csv(&curve))?;
    if let Some(path) = history {
        let mut text = String::from("t_s,depth_mm,base_load_n,contact_n\n");
        for h in &curve.history {
            text += &format!("{:.6e},{:.6e},{:.6e},{:.6e}\n", h[0], h[1], h[2], h[3]);
        }
        write(&path, &text)?;
    }
    plot(&curve, &svg)?;
    println!("wrote {} and {}", csv.display(), svg.display());
    Ok(())
}

fn set(setup: &mut Setup, kv: &str) -> Result<(), Box<dyn Error>> {
    let (k, v) = kv.split_once('=').ok_or("--set needs key=value")?;
    let f = || v.parse::<f64>();
    match k {
        "thickness" => setup.thickness = f()?,
        "width" => setup.width = f()?,
        "spacing" => setup.spacing = f()?,
        "radius" => setup.radius = f()?,
        "ball_spacing" => setup.ball_spacing = f()?,
        "damping" => setup.damping = f()?,
        "magnitude" => setup.magnitude = if v == "auto" { None } else { Some(f()?) },
        "ramp" => setup.ramp = f()?,
        "hold" => setup.hold = f()?,
        "window" => setup.window = f()?,
        "depths" => setup.depths = v.split(',').map(str::parse).collect::<Result<_, _>>()?,
        "stiffening" => setup.stiffening = Some(v.parse()?),
        "model" => setup.model = v.to_string(),
        "poisson" => setup.poisson = f()?,
        "young_kpa" => setup.young_kpa = f()?,
        _ => return Err(format!("--set: unknown key {k}").into()),
    }
    Ok(())
}

fn write(path: &Path, text: &str) -> Result<(), Box<dyn Error>> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    std::fs::write(path, text).map_err(|e| format!("{}: {e}", path.display()).into())
}

fn samples_csv(curve: &Curve) -> String {
    let mut text = String::from(
        "depth_pct_t,depth_mm,base_load_n,contact_n,hertz_r_n,hertz_r_plus_radius_n,bonded_layer_n,ratio\n",
    );
    for s in &curve.samples {
        text += &format!(
            "{:.1},{:.4},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.4}\n",
            100.0 * s.depth / curve.setup.thickness,
            s.depth,
            s.reaction,
            s.contact,
            s.hertz,
            s.hertz_envelope,
            s.layer,
            s.ratio()
        );
    }
    text
}

/// Force against depth: the measured base load and contact force, Hertz's curve for `R + r`
/// with its ±25 % band, and the bonded layer's curve; forces in mN.
fn plot(curve: &Curve, path: &Path) -> Result<(), Box<dyn Error>> {
    let s = &curve.setup;
    let envelope = s.radius + curve.contact_radius;
    let nu = s.effective_poisson();
    let hertz_mn = |d: f64| 1e3 * hertz::hertz(s.young_kpa, nu, envelope, d);
    let layer_mn = |d: f64| hertz_mn(d) * bonded_layer(nu, envelope, d, s.thickness);
    let d_max = 1.1 * curve.samples.iter().map(|p| p.depth).fold(0.0, f64::max);
    let f_max = 1.3 * hertz_mn(d_max);
    let xs: Vec<f64> = (0..=200).map(|i| d_max * f64::from(i) / 200.0).collect();

    let (width, height) = (960u32, 880u32);
    let mut text = String::new();
    {
        let area = SVGBackend::with_string(&mut text, (width, height)).into_drawing_area();
        area.fill(&WHITE)?;
        let (top, bottom) = area.split_vertically(600);
        let mut chart = ChartBuilder::on(&top)
            .caption(
                format!(
                    "Rigid sphere R = {} mm into a {} × {} × {} mm block, E = {} kPa ({})",
                    s.radius,
                    s.width,
                    s.width,
                    s.thickness,
                    s.young_kpa,
                    if s.model == "springs" {
                        "lattice ν = 1/4".to_string()
                    } else {
                        format!("{}, ν = {}", s.model, s.poisson)
                    }
                ),
                ("sans-serif", 21),
            )
            .margin(18)
            .x_label_area_size(52)
            .y_label_area_size(70)
            .top_x_label_area_size(44)
            .build_cartesian_2d(0.0..d_max, 0.0..f_max)?
            .set_secondary_coord(0.0..100.0 * d_max / s.thickness, 0.0..f_max);
        chart
            .configure_mesh()
            .x_desc("depth past first contact d (mm)")
            .y_desc("indenting force F (mN)")
            .label_style(("sans-serif", 16))
            .axis_desc_style(("sans-serif", 18))
            .light_line_style(WHITE.mix(0.0))
            .draw()?;
        chart
            .configure_secondary_axes()
            .x_desc("depth (% of block thickness T)")
            .label_style(("sans-serif", 16))
            .axis_desc_style(("sans-serif", 18))
            .draw()?;
        let blue = RGBColor(31, 119, 180);
        let band: Vec<(f64, f64)> = xs
            .iter()
            .map(|&d| (d, 1.25 * hertz_mn(d)))
            .chain(xs.iter().rev().map(|&d| (d, 0.75 * hertz_mn(d))))
            .collect();
        chart
            .draw_series(std::iter::once(Polygon::new(band, blue.mix(0.15).filled())))?
            .label("Hertz ± 25 % (the test's band)")
            .legend(move |(x, y)| Rectangle::new([(x, y - 6), (x + 20, y + 6)], blue.mix(0.15).filled()));
        chart
            .draw_series(LineSeries::new(xs.iter().map(|&d| (d, hertz_mn(d))), blue.stroke_width(2)))?
            .label(format!("Hertz, 4/3 E/(1−ν²) √(R + r) d^1.5, R + r = {envelope} mm"))
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], blue.stroke_width(2)));
        chart
            .draw_series(DashedLineSeries::new(
                xs.iter().map(|&d| (d, layer_mn(d))),
                6,
                4,
                BLACK.mix(0.6).stroke_width(2),
            ))?
            .label(format!("Hertz for a layer of T = {} mm bonded to its base (dashed)", s.thickness))
            .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLACK.mix(0.6).stroke_width(2)));
        let red = RGBColor(214, 39, 40);
        chart
            .draw_series(
                curve.samples.iter().map(|p| Circle::new((p.depth, 1e3 * p.reaction), 6, red.filled())),
            )?
            .label("measured: load through the pinned base")
            .legend(move |(x, y)| Circle::new((x + 10, y), 5, red.filled()));
        chart
            .draw_series(
                curve
                    .samples
                    .iter()
                    .map(|p| Cross::new((p.depth, 1e3 * p.contact), 7, BLACK.stroke_width(2))),
            )?
            .label("measured: contact force, time-averaged")
            .legend(|(x, y)| Cross::new((x + 10, y), 5, BLACK.stroke_width(2)));
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .label_font(("sans-serif", 16))
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK.mix(0.4))
            .draw()?;

        // The ratios, where the band is the test's bounds.
        let mut ratios = ChartBuilder::on(&bottom)
            .margin(18)
            .margin_top(4)
            .x_label_area_size(52)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..d_max, 0.7..1.3)?;
        ratios
            .configure_mesh()
            .x_desc("depth past first contact d (mm)")
            .y_desc("measured / Hertz (R + r)")
            .label_style(("sans-serif", 16))
            .axis_desc_style(("sans-serif", 18))
            .light_line_style(WHITE.mix(0.0))
            .draw()?;
        ratios.draw_series(std::iter::once(Rectangle::new(
            [(0.0, 0.75), (d_max, 1.25)],
            blue.mix(0.15).filled(),
        )))?;
        ratios.draw_series(LineSeries::new([(0.0, 1.0), (d_max, 1.0)], blue.stroke_width(2)))?;
        ratios
            .draw_series(DashedLineSeries::new(
                xs.iter().skip(1).map(|&d| (d, layer_mn(d) / hertz_mn(d))),
                6,
                4,
                BLACK.mix(0.6).stroke_width(2),
            ))?
            .label("bonded layer / Hertz")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLACK.mix(0.6).stroke_width(2)));
        ratios
            .draw_series(curve.samples.iter().map(|p| Circle::new((p.depth, p.ratio()), 6, red.filled())))?
            .label("base load / Hertz")
            .legend(move |(x, y)| Circle::new((x + 10, y), 5, red.filled()));
        ratios
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerRight)
            .label_font(("sans-serif", 16))
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK.mix(0.4))
            .draw()?;
        area.present()?;
    }
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    std::fs::write(path, text).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(())
}
