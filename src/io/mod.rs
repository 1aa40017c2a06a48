//! Files lancer reads and writes: images (PNG, EXR) with the render's
//! settings as metadata, written atomically, and the film files of split
//! renders, and the check that a run's outputs name no other of its files.

pub mod film;
pub mod image_file;
pub mod run_files;
