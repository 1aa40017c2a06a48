//! Files lancer reads and writes: images (PNG, EXR) with the render's
//! settings as metadata, written atomically, and the film files of split
//! renders.

pub mod film;
pub mod image_file;
