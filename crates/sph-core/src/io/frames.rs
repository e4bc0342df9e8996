//! Numbered frames in a folder with their CSV index.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use super::{Format, PointCloud, io_err};
use crate::error::{Error, Result};

/// Writes numbered frames `{prefix}_{frame:05}.{ext}` into a folder and keeps
/// `{prefix}_index.csv` (frame, time, points, file) up to date after each frame.
#[derive(Debug)]
pub struct FrameWriter {
    dir: PathBuf,
    prefix: String,
    format: Format,
    index: BufWriter<File>,
    frames: u64,
}

impl FrameWriter {
    /// Creates `dir` if needed and starts a fresh index there.
    pub fn new(dir: impl AsRef<Path>, prefix: &str, format: Format) -> Result<Self> {
        let dir = dir.as_ref().to_path_buf();
        let path_str = dir.display().to_string();
        std::fs::create_dir_all(&dir).map_err(|e| io_err(&path_str, e))?;
        let index_path = dir.join(format!("{prefix}_index.csv"));
        let index_str = index_path.display().to_string();
        let file = File::create(&index_path).map_err(|e| io_err(&index_str, e))?;
        let mut index = BufWriter::new(file);
        writeln!(index, "frame,time,points,file").map_err(|e| io_err(&index_str, e))?;
        Ok(Self {
            dir,
            prefix: prefix.to_string(),
            format,
            index,
            frames: 0,
        })
    }

    /// Writes the next frame; returns its path.
    pub fn write(&mut self, cloud: &PointCloud, time: f64) -> Result<PathBuf> {
        let name = format!(
            "{}_{:05}.{}",
            self.prefix,
            self.frames,
            self.format.extension()
        );
        let path = self.dir.join(&name);
        let path_str = path.display().to_string();
        let file = File::create(&path).map_err(|e| io_err(&path_str, e))?;
        self.format.write(file, cloud, time).map_err(|e| match e {
            Error::Io { reason, .. } => io_err(&path_str, std::io::Error::other(reason)),
            other => other,
        })?;
        let index = &mut self.index;
        writeln!(index, "{},{time:?},{},{name}", self.frames, cloud.len())
            .and_then(|_| index.flush())
            .map_err(|e| io_err(&self.dir.display().to_string(), e))?;
        self.frames += 1;
        Ok(path)
    }

    /// Frames written so far.
    pub fn frames(&self) -> u64 {
        self.frames
    }
}
