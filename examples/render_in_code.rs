//! Builds a scene in code, renders it and writes `sphere.png` with its settings.
use lancer::scene::{MaterialKind, SceneBuilder, SceneError};
use lancer::{Context, ContextOptions, RenderOptions, Renderer, Scene, Vec3};

/// A glass sphere on a white floor under a square lamp and a grey sky.
#[rustfmt::skip]
pub fn scene() -> Result<Scene, SceneError> {
    let v = Vec3::new;
    SceneBuilder::new(64, 64, 16)
        .camera(v(0.0, 1.0, 4.0), v(0.0, 0.75, 0.0), 40.0)
        .environment(Vec3::splat(0.25))
        .material("white", MaterialKind::lambert(Vec3::splat(0.75)))
        .material("glass", MaterialKind::dielectric(1.5))
        .emitter("lamp", MaterialKind::lambert(Vec3::ZERO), Vec3::splat(10.0))
        .quad(v(-2.0, 0.0, -2.0), v(0.0, 0.0, 4.0), v(4.0, 0.0, 0.0), "white")
        .quad(v(-0.5, 2.5, -0.5), v(1.0, 0.0, 0.0), v(0.0, 0.0, 1.0), "lamp")
        .sphere(v(0.0, 0.75, 0.0), 0.75, "glass")
        .build()
}

fn main() -> anyhow::Result<()> {
    let device = Context::new(&ContextOptions::default())?;
    let mut renderer = Renderer::new(&device, &scene()?, &RenderOptions::default())?;
    let image = renderer.render(None)?;
    println!("{}", image.stats.table());
    lancer::io::image_file::write_render("sphere.png".as_ref(), &image)
}
