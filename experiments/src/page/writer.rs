//! Writing the page's files into the output folder, keeping the list of
//! files written.

use std::path::PathBuf;

use crate::PaperError;
use crate::figures::{Panel, plot};
use crate::report::{Cells, Table};

/// Writes files under `docs` and remembers each path.
pub(super) struct Writer {
    /// The folder the page and its files go to.
    pub(super) docs: PathBuf,
    /// Every file written so far, in order.
    pub(super) written: Vec<PathBuf>,
}

impl Writer {
    fn path(&mut self, name: &str) -> PathBuf {
        let p = self.docs.join(name);
        self.written.push(p.clone());
        p
    }

    pub(super) fn text(&mut self, name: &str, text: &str) -> Result<(), PaperError> {
        let p = self.path(name);
        std::fs::write(&p, text).map_err(|e| PaperError::io("write", &p, e))
    }

    pub(super) fn csv(&mut self, name: &str, t: &Table) -> Result<(), PaperError> {
        let p = self.path(name);
        t.write_csv(&p)
    }

    pub(super) fn cells(&mut self, name: &str, c: &Cells) -> Result<(), PaperError> {
        let p = self.path(name);
        c.write(&p)
    }

    pub(super) fn plot(
        &mut self,
        stem: &str,
        panels: &[Panel],
        width: u32,
        height: u32,
    ) -> Result<(), PaperError> {
        let p = self.docs.join(stem);
        plot(&p, panels, width, height)?;
        self.written.push(p.with_extension("png"));
        self.written.push(p.with_extension("svg"));
        Ok(())
    }
}
