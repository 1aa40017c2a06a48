//! The library's messages name the setting to change (`RenderOptions::wave_size`,
//! `Budget::Time`); this command line calls them by its flags. [`named`]
//! rewrites a message the library wrote into the command line's words, for
//! every error and warning any command prints.

/// What the library's messages say, and what this command line says for it:
/// a setting and its flag, or a phrase around a setting where the flag reads
/// differently. Longer phrases come before the names they contain.
const SETTINGS: &[(&str, &str)] = &[
    // Renderer
    (
        "the paths in flight (RenderOptions::wave_size) must be at least 1",
        "--wave-size must be at least 1",
    ),
    ("RenderOptions::wave_size", "--wave-size"),
    (
        "the BSDF-sampling estimator (RenderOptions::integrator Bsdf): remove the property and choose that estimator",
        "--integrator bsdf: remove the property and pass the flag",
    ),
    // Scene settings the command line overrides
    (
        "the value of RenderOverrides::width",
        "the value of --width",
    ),
    (
        "the value of RenderOverrides::height",
        "the value of --height",
    ),
    ("the value of RenderOverrides::spp", "the value of --spp"),
    (
        "the value of RenderOverrides::max_depth",
        "the value of --max-depth",
    ),
    ("the value of RenderOverrides::seed", "the value of --seed"),
    (
        "the width or height (render.width, render.height)",
        "the width or height (in the scene, or --width / --height)",
    ),
    ("(render.width, render.height)", "(--width, --height)"),
    (
        "or render.max_depth to at most",
        "or render.max_depth (in the scene, or --max-depth) to at most",
    ),
    (
        "no Vulkan device matches ContextOptions::device",
        "no Vulkan device matches --device",
    ),
    // Budgets: `render --time-limit/--target-error`, `converge --time-limit`
    ("Budget::Time", "--time-limit"),
    ("Budget::Error", "--target-error"),
    ("render_with_budget(max_spp)", "--max-spp"),
    // compare
    ("CompareOptions::max_relmse", "--max-relmse"),
    ("CompareOptions::max_flip", "--max-flip"),
    ("CompareOptions::heatmap", "--heatmap"),
    ("CompareOptions::json", "--json"),
    // converge
    ("study::Vary", "--vary"),
    (
        "render one with study::rendered_reference",
        "use --reference-spp N",
    ),
    ("study::rendered_reference(spp)", "--reference-spp"),
    ("study::run(seeds)", "--seeds"),
    (
        "or set render.width/render.height to match",
        "or pass --width/--height to match",
    ),
];

/// `message` with every setting of [`SETTINGS`] it names replaced by the
/// command line's flag.
pub fn named(message: &str) -> String {
    SETTINGS
        .iter()
        .fold(message.to_string(), |text, (setting, flag)| {
            text.replace(setting, flag)
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_become_flags_and_the_rest_stays() {
        assert_eq!(
            named("Budget::Time must be a number of seconds above 0, got 0"),
            "--time-limit must be a number of seconds above 0, got 0"
        );
        assert_eq!(
            named("the paths in flight (RenderOptions::wave_size) must be at least 1"),
            "--wave-size must be at least 1"
        );
        assert_eq!(
            named("lower the paths in flight, 4096 (RenderOptions::wave_size)"),
            "lower the paths in flight, 4096 (--wave-size)"
        );
        // Scene keys in a scene's own errors are not flags
        let scene = "t.toml:2: render.width: must be >= 1, got 0";
        assert_eq!(named(scene), scene);
    }

    #[test]
    fn no_flag_is_named_twice_or_rewritten_again() {
        for (i, (setting, flag)) in SETTINGS.iter().enumerate() {
            // A later entry would rewrite this one's flag
            for (later, _) in &SETTINGS[i + 1..] {
                assert!(!flag.contains(later), "{flag} contains {later}");
            }
            // A phrase is rewritten whole, before a name inside it
            for (earlier, _) in &SETTINGS[..i] {
                assert!(!setting.contains(earlier), "{earlier} goes after {setting}");
            }
        }
    }
}
