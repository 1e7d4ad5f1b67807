//! `terraclip export` and its reader: the files are the frame. Every golden
//! scene is exported, read back as a plain mesh (positions and varyings,
//! no clipmap), drawn again on the CPU and compared with the reference
//! bits; corrupt, truncated and mislabelled exports are clean errors that
//! name the file.

use std::path::{Path, PathBuf};
use terraclip::export;
use terraclip::frame::stats::Passes;
use terraclip::render::{draw, RenderOptions};
use terraclip::scene::Scene;

fn tmp(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("export")
        .join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(d.parent().unwrap()).unwrap();
    d
}

fn export_golden(name: &str, dir: &Path) -> export::Written {
    let path = PathBuf::from(format!("golden/{name}.toml"));
    let scene = Scene::load(&path).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    export::scene(&scene, name, Some(&text), 1, 0.0, dir).unwrap()
}

/// Every golden scene, drawn from its exported files alone, gives the
/// exported reference bit for bit, and that reference is the golden PNG.
#[test]
fn every_golden_redrawn_from_its_export_is_the_reference() {
    let scenes = terraclip::check::golden::scenes(Path::new("golden")).unwrap();
    assert!(scenes.len() >= 15);
    for p in scenes {
        let name = p.file_stem().unwrap().to_string_lossy().into_owned();
        let dir = tmp(&format!("golden-{name}"));
        let w = export_golden(&name, &dir);
        let e = export::read(&dir).unwrap();
        assert_eq!(e.frame.triangle_count(), w.frames[0].triangles, "{name}");
        let (img, _) = draw(&e.frame, &RenderOptions::default(), &mut Passes::default());
        let differ = img
            .rgba
            .chunks(4)
            .zip(e.image.rgba.chunks(4))
            .filter(|(a, b)| a != b)
            .count();
        let depth = img
            .depth
            .iter()
            .zip(&e.image.depth)
            .filter(|(a, b)| a.to_bits() != b.to_bits())
            .count();
        eprintln!(
            "{name}: {} triangles, {differ} colour px, {depth} depth px differ",
            e.frame.triangle_count()
        );
        assert_eq!((differ, depth), (0, 0), "{name}");
        let (gw, gh, golden) =
            terraclip::check::golden::load_png(&p.with_extension("png")).unwrap();
        assert_eq!((gw, gh), (img.width, img.height), "{name}");
        assert!(
            golden == e.image.rgba,
            "{name}: the export's colour is not the golden"
        );
    }
}
