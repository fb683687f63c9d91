//! An episode's label file, `DIR/labels-NNNNN.safetensors`: the action values
//! the labeller wrote for every frame and view, and which frames have one.

use std::collections::HashMap;
use std::path::Path;

use ::safetensors::tensor::Dtype;
use memmap2::Mmap;

use super::safetensors::{
    bytes_of, check_format, expect_shape, f32s, map_file, offset_in, parse, serialize, st_metadata,
    tensor,
};
use super::{DataError, FORMAT};

/// Action values of one episode: what a label file holds.
#[derive(Debug, Clone, PartialEq)]
pub struct Labels {
    /// Views per frame.
    pub views: usize,
    /// `N x V x 6 x 4 x 28` raw action values.
    pub q: Vec<f32>,
    /// Whether each frame has a label (its whole future was driven).
    pub valid: Vec<bool>,
}

/// Commands, speed bins and actions of one label: 6 x 4 x 28.
pub const Q_PER_VIEW: usize = 6 * 4 * 28;

impl Labels {
    /// The label of `frame` seen from `view`: `[6][4][28]` flattened.
    pub fn q(&self, frame: usize, view: usize) -> &[f32] {
        let at = (frame * self.views + view) * Q_PER_VIEW;
        &self.q[at..at + Q_PER_VIEW]
    }

    /// The safetensors bytes, with the label version in the metadata.
    pub fn to_bytes(&self, label_version: u32, shard: &str) -> Vec<u8> {
        let n = self.valid.len();
        let valid: Vec<u8> = self.valid.iter().map(|&v| u8::from(v)).collect();
        let metadata = HashMap::from([
            ("format".to_string(), FORMAT.to_string()),
            ("label_version".to_string(), label_version.to_string()),
            ("shard".to_string(), shard.to_string()),
        ]);
        serialize(
            vec![
                (
                    "q",
                    Dtype::F32,
                    vec![n, self.views, 6, 4, 28],
                    bytes_of(&self.q),
                ),
                ("valid", Dtype::U8, vec![n], &valid),
            ],
            &metadata,
        )
    }

    /// Reads a label file, refusing another label version or frame count.
    pub fn read(
        path: &Path,
        label_version: u32,
        frames: usize,
        views: usize,
    ) -> Result<Labels, DataError> {
        MappedLabels::open(path, label_version, frames, views).map(|m| m.to_labels())
    }
}

/// A label file opened by memory map: checked once when opened (version,
/// shapes, finite values), then read one label at a time.
#[derive(Debug)]
pub struct MappedLabels {
    map: Mmap,
    q_at: usize,
    views: usize,
    /// Whether each frame has a label (its whole future was driven).
    pub valid: Vec<bool>,
}

impl MappedLabels {
    /// Maps a label file, refusing another label version, frame or view count.
    pub fn open(
        path: &Path,
        label_version: u32,
        frames: usize,
        views: usize,
    ) -> Result<MappedLabels, DataError> {
        let map = map_file(path)?;
        let st = parse(path, &map)?;
        let meta = st_metadata(path, &map)?;
        check_format(path, &meta)?;
        let version = meta
            .get("label_version")
            .map(String::as_str)
            .unwrap_or("none");
        if version != label_version.to_string() {
            return Err(DataError::shard(
                path,
                "label_version",
                format!(
                    "labels are version {version}, this build makes version {label_version}; run `mrdrive label` on the dataset again"
                ),
            ));
        }
        let q = tensor(path, &st, "q", Dtype::F32)?;
        expect_shape(
            path,
            "q",
            q.shape(),
            &[frames, views, 6, 4, 28],
            "frames and views (label again)",
        )?;
        let valid = tensor(path, &st, "valid", Dtype::U8)?;
        expect_shape(
            path,
            "valid",
            valid.shape(),
            &[frames],
            "frames (label again)",
        )?;
        if q.data()
            .chunks_exact(4)
            .any(|b| !f32::from_le_bytes([b[0], b[1], b[2], b[3]]).is_finite())
        {
            return Err(DataError::shard(
                path,
                "q",
                "non-finite action values; run `mrdrive label` again",
            ));
        }
        let valid = valid.data().iter().map(|&v| v != 0).collect();
        let q_at = offset_in(&map, q.data());
        Ok(MappedLabels {
            map,
            q_at,
            views,
            valid,
        })
    }

    /// Writes the label of `frame` seen from `view` (`[6][4][28]` flattened) into `out`.
    pub fn q_into(&self, frame: usize, view: usize, out: &mut [f32]) {
        let at = self.q_at + (frame * self.views + view) * Q_PER_VIEW * 4;
        let bytes = &self.map[at..at + Q_PER_VIEW * 4];
        for (o, b) in out[..Q_PER_VIEW].iter_mut().zip(bytes.chunks_exact(4)) {
            *o = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        }
    }

    /// The whole label file in memory.
    pub fn to_labels(&self) -> Labels {
        let n = self.valid.len() * self.views * Q_PER_VIEW * 4;
        Labels {
            views: self.views,
            q: f32s(&self.map[self.q_at..self.q_at + n]),
            valid: self.valid.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::file_metadata;

    #[test]
    fn mapped_labels_give_each_label_as_written() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("labels-00000.safetensors");
        let labels = Labels {
            views: 2,
            q: (0..3 * 2 * Q_PER_VIEW).map(|i| i as f32 * 0.5).collect(),
            valid: vec![true, true, false],
        };
        std::fs::write(&path, labels.to_bytes(4, "episode-00000.safetensors")).unwrap();
        let mapped = MappedLabels::open(&path, 4, 3, 2).unwrap();
        let mut out = vec![0.0; Q_PER_VIEW];
        mapped.q_into(2, 1, &mut out);
        assert_eq!(out, labels.q(2, 1));
        assert_eq!(mapped.valid, labels.valid);
        assert_eq!(file_metadata(&path).unwrap()["label_version"], "4");
    }

    #[test]
    fn labels_of_another_version_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("labels-00000.safetensors");
        let labels = Labels {
            views: 1,
            q: vec![0.5; 2 * Q_PER_VIEW],
            valid: vec![true, false],
        };
        std::fs::write(&path, labels.to_bytes(1, "episode-00000.safetensors")).unwrap();
        assert_eq!(Labels::read(&path, 1, 2, 1).unwrap(), labels);
        let err = Labels::read(&path, 2, 2, 1).unwrap_err().to_string();
        assert!(
            err.contains("label_version") && err.contains("mrdrive label"),
            "{err}"
        );
    }
}
