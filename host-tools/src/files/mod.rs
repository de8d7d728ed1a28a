//! The project's file formats, apart from the algorithms that read and
//! write them: scenarios, plant files, gains files, calibration files.
pub mod plant;
pub mod scenario;
