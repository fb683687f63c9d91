//! The safetensors files of a dataset, shards and labels alike: writing them
//! with a canonical header (the same bytes for the same data), mapping them,
//! and the checked reading of their header, format tag and tensors.

use std::collections::HashMap;
use std::path::Path;

use ::safetensors::tensor::{Dtype, SafeTensors, TensorView};
use memmap2::Mmap;

use super::{DataError, FORMAT};

/// The metadata in a dataset file's header (the format tag, the label
/// version of a label file), read without reading its tensors.
pub fn file_metadata(path: &Path) -> Result<HashMap<String, String>, DataError> {
    let map = map_file(path)?;
    st_metadata(path, &map)
}

/// Maps a whole file read-only.
pub(super) fn map_file(path: &Path) -> Result<Mmap, DataError> {
    let file = std::fs::File::open(path).map_err(|e| DataError::io(path, e))?;
    // SAFETY: dataset files are replaced by rename, never written in place
    // (`write_atomic`), so the mapped bytes stay as they are while mapped.
    unsafe { Mmap::map(&file) }.map_err(|e| DataError::io(path, e))
}

/// Where `part` (a slice of `whole`) starts in `whole` (bytes).
pub(super) fn offset_in(whole: &[u8], part: &[u8]) -> usize {
    part.as_ptr() as usize - whole.as_ptr() as usize
}

pub(super) fn serialize(
    tensors: Vec<(&str, Dtype, Vec<usize>, &[u8])>,
    metadata: &HashMap<String, String>,
) -> Vec<u8> {
    let views: Vec<(String, TensorView<'_>)> = tensors
        .into_iter()
        .map(|(name, dtype, shape, data)| {
            (
                name.to_string(),
                TensorView::new(dtype, shape, data).expect("shapes match the data by construction"),
            )
        })
        .collect();
    let mut meta = metadata.clone();
    meta.entry("format".into())
        .or_insert_with(|| FORMAT.to_string());
    let bytes =
        ::safetensors::serialize(views, Some(meta)).expect("in-memory serialisation cannot fail");
    canonical_header(bytes)
}

/// The same file with its JSON header's keys in sorted order: safetensors
/// writes the metadata map in hash order, which differs from map to map, and
/// a dataset must be the same bytes for the same plan. The sorted header has
/// the same length, so the data offsets stay as they are.
pub(super) fn canonical_header(mut bytes: Vec<u8>) -> Vec<u8> {
    fn sorted(v: serde_json::Value) -> serde_json::Value {
        match v {
            serde_json::Value::Object(m) => {
                let tree: std::collections::BTreeMap<String, serde_json::Value> =
                    m.into_iter().map(|(k, v)| (k, sorted(v))).collect();
                serde_json::to_value(tree).expect("a map of JSON values")
            }
            other => other,
        }
    }
    let n = u64::from_le_bytes(bytes[..8].try_into().expect("8 bytes")) as usize;
    let header: serde_json::Value =
        serde_json::from_slice(&bytes[8..8 + n]).expect("safetensors wrote JSON");
    let mut text = serde_json::to_vec(&sorted(header)).expect("JSON serialises");
    assert!(
        text.len() <= n,
        "a sorted header is no longer than the original"
    );
    text.resize(n, b' ');
    bytes[8..8 + n].copy_from_slice(&text);
    bytes
}

pub(super) fn parse<'a>(path: &Path, bytes: &'a [u8]) -> Result<SafeTensors<'a>, DataError> {
    SafeTensors::deserialize(bytes).map_err(|e| {
        DataError::shard(
            path,
            "header",
            format!("not a readable safetensors file ({e}); it may be truncated: delete it and collect (or label) again"),
        )
    })
}

pub(super) fn st_metadata(path: &Path, bytes: &[u8]) -> Result<HashMap<String, String>, DataError> {
    let (_, meta) = SafeTensors::read_metadata(bytes).map_err(|e| {
        DataError::shard(
            path,
            "header",
            format!("unreadable header ({e}); it may be truncated: delete it and collect (or label) again"),
        )
    })?;
    Ok(meta.metadata().clone().unwrap_or_default())
}

pub(super) fn check_format(path: &Path, meta: &HashMap<String, String>) -> Result<(), DataError> {
    match meta.get("format") {
        Some(f) if f == FORMAT => Ok(()),
        other => Err(DataError::shard(
            path,
            "format",
            format!(
                "format is {other:?}, this build reads {FORMAT:?}; collect again with this build"
            ),
        )),
    }
}

pub(super) fn tensor<'a>(
    path: &Path,
    st: &'a SafeTensors<'a>,
    name: &str,
    dtype: Dtype,
) -> Result<TensorView<'a>, DataError> {
    let t = st.tensor(name).map_err(|_| {
        DataError::shard(
            path,
            name,
            "missing; this is not a complete mrdrive shard: collect this episode again",
        )
    })?;
    if t.dtype() != dtype {
        return Err(DataError::shard(
            path,
            name,
            format!("dtype {:?}, expected {dtype:?}", t.dtype()),
        ));
    }
    Ok(t)
}

pub(super) fn expect_shape(
    path: &Path,
    name: &str,
    got: &[usize],
    want: &[usize],
    what: &str,
) -> Result<(), DataError> {
    if got == want {
        Ok(())
    } else {
        Err(DataError::shard(
            path,
            name,
            format!(
                "shape {got:?}, expected {want:?} from the index's {what}: this shard belongs to another dataset or S0; collect it again"
            ),
        ))
    }
}

pub(super) fn bytes_of<T: Copy>(v: &[T]) -> &[u8] {
    // f32 and u32 have no padding and any bit pattern is a valid u8.
    unsafe { std::slice::from_raw_parts(v.as_ptr().cast::<u8>(), std::mem::size_of_val(v)) }
}

pub(super) fn f32s(bytes: &[u8]) -> Vec<f32> {
    bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}
