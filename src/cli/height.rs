//! `terraclip height`: heights and ray hits on the surface as rendered.

use super::SceneArgs;
use glam::DVec3;
use serde_json::json;
use std::path::PathBuf;
use terraclip::render::Session;

#[derive(clap::Args, Debug)]
pub struct Args {
    pub scene: Option<PathBuf>,
    /// A world point X,Y (repeatable).
    #[arg(long = "at", value_parser = parse_xy, allow_hyphen_values = true)]
    pub at: Vec<[f64; 2]>,
    /// A ray OX,OY,OZ,DX,DY,DZ (repeatable).
    #[arg(long, value_parser = parse_ray, allow_hyphen_values = true)]
    pub ray: Vec<[f64; 6]>,
    #[command(flatten)]
    pub args: SceneArgs,
    #[arg(long)]
    pub json: bool,
}

/// `N` comma-separated finite numbers.
fn parse_numbers<const N: usize>(s: &str) -> Result<[f64; N], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>().map_err(|e| format!("'{p}': {e}")))
        .collect::<Result<_, _>>()?;
    let a: [f64; N] = v
        .try_into()
        .map_err(|v: Vec<f64>| format!("need {N} comma-separated numbers, got {}", v.len()))?;
    if a.iter().all(|x| x.is_finite()) {
        Ok(a)
    } else {
        Err("values must be finite".into())
    }
}

fn parse_xy(s: &str) -> Result<[f64; 2], String> {
    parse_numbers::<2>(s)
}

fn parse_ray(s: &str) -> Result<[f64; 6], String> {
    let r = parse_numbers::<6>(s)?;
    if r[3..] == [0.0; 3] {
        return Err("the ray direction must not be zero".into());
    }
    Ok(r)
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let s = a
        .args
        .scene(&a.scene, terraclip::scene::Scene::default_scene)?;
    let mut session = Session::new(&s, &mut Default::default())?;
    let surface = session.surface(&s.camera())?;
    let points: Vec<_> =
        a.at.iter()
            .map(|&[x, y]| json!({"x": x, "y": y, "height": surface.height_at(x, y)}))
            .collect();
    let hits: Vec<_> = a
        .ray
        .iter()
        .map(|r| {
            let (o, d) = (DVec3::new(r[0], r[1], r[2]), DVec3::new(r[3], r[4], r[5]));
            let h = surface.ray_hit(o, d);
            json!({"origin": [r[0], r[1], r[2]], "dir": [r[3], r[4], r[5]],
                   "t": h.map(|h| h.t), "point": h.map(|h| h.point.to_array())})
        })
        .collect();
    if a.json {
        println!("{}", json!({"points": points, "rays": hits}));
        return Ok(());
    }
    for p in &points {
        println!("height at ({}, {}): {}", p["x"], p["y"], p["height"]);
    }
    for h in &hits {
        println!(
            "ray from {} along {}: t = {}, hit {}",
            h["origin"], h["dir"], h["t"], h["point"]
        );
    }
    Ok(())
}
