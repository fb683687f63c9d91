//! The wire format of `mrdrive serve`: every message, either way, is a frame: a
//! little-endian `u32` length, that many bytes of UTF-8 JSON, a little-endian `u64`
//! length, that many payload bytes (an image, or nothing).

use std::io::{self, Read, Write};

use serde_json::Value;

/// The largest payload a frame may announce (bytes); a larger length means a corrupt frame.
pub const MAX_PAYLOAD_BYTES: u64 = 1 << 30;

/// Reads one frame; `None` at a clean end of input (before a frame's first byte).
pub fn read_frame(r: &mut impl Read) -> io::Result<Option<(Value, Vec<u8>)>> {
    let mut len = [0u8; 4];
    match r.read_exact(&mut len) {
        Ok(()) => {}
        Err(e) if e.kind() == io::ErrorKind::UnexpectedEof => return Ok(None),
        Err(e) => return Err(e),
    }
    let mut text = vec![0u8; u32::from_le_bytes(len) as usize];
    r.read_exact(&mut text)?;
    let mut plen = [0u8; 8];
    r.read_exact(&mut plen)?;
    let n = u64::from_le_bytes(plen);
    if n > MAX_PAYLOAD_BYTES {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!("a payload of {n} bytes: the frame is corrupt"),
        ));
    }
    let mut payload = vec![0u8; n as usize];
    r.read_exact(&mut payload)?;
    let value = serde_json::from_slice(&text).map_err(|e| {
        io::Error::new(
            io::ErrorKind::InvalidData,
            format!("the request is not JSON: {e}"),
        )
    })?;
    Ok(Some((value, payload)))
}

/// Writes one frame and flushes it.
pub fn write_frame(w: &mut impl Write, value: &Value, payload: &[u8]) -> io::Result<()> {
    let text = serde_json::to_vec(value).expect("a JSON value serialises");
    w.write_all(&(text.len() as u32).to_le_bytes())?;
    w.write_all(&text)?;
    w.write_all(&(payload.len() as u64).to_le_bytes())?;
    w.write_all(payload)?;
    w.flush()
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn frames_round_trip_and_a_truncated_frame_is_an_error() {
        let mut buf = Vec::new();
        write_frame(
            &mut buf,
            &json!({"op": "step", "control": [0.0, 0.5, 0.0]}),
            &[1, 2, 3],
        )
        .unwrap();
        let (v, p) = read_frame(&mut buf.as_slice()).unwrap().unwrap();
        assert_eq!(v["op"], "step");
        assert_eq!(p, vec![1, 2, 3]);
        assert!(read_frame(&mut [].as_slice()).unwrap().is_none());
        let truncated: &[u8] = &buf[..buf.len() - 1];
        assert!(read_frame(&mut &*truncated).is_err());
    }

    #[test]
    fn a_frame_that_is_not_json_is_invalid_data() {
        let mut buf = Vec::new();
        buf.extend_from_slice(&3u32.to_le_bytes());
        buf.extend_from_slice(b"{x}");
        buf.extend_from_slice(&0u64.to_le_bytes());
        let e = read_frame(&mut buf.as_slice()).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidData);
        assert!(e.to_string().contains("not JSON"), "{e}");
    }
}
