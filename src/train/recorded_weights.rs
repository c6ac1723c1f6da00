//! The sha256 a policy's or value network's weights were recorded with when they were made,
//! so weights changed since are refused wherever they load (evaluation, a warm start, a KL
//! reference, an average): a checkpoint's own `state.json`, a finished run's newest
//! checkpoint, and a model folder's `averaged.json` (`rtr model average`) or `CARD.md`
//! (a line `**Weights:** `policy.bpk` sha256 `<64 hex digits>``).

use std::path::{Path, PathBuf};

use crate::data::automatum::sha256_hex;
use crate::error::{Error, Result};

use super::checkpoint::{POLICY, STATE, latest, read_state};

/// The card line's text before the digest.
pub const CARD_WEIGHTS: &str = "`policy.bpk` sha256 `";

/// Checks the tensor file `path`, read as `bytes`, against the sha256 recorded for it. Files
/// without a record (a folder of the user's, checkpoints written before checksums were kept)
/// are not checked.
pub(super) fn verify(path: &Path, bytes: &[u8]) -> Result<()> {
    let Some((expected, record)) = recorded(path)? else {
        return Ok(());
    };
    let actual = sha256_hex(bytes);
    if actual == expected {
        return Ok(());
    }
    Err(Error::invalid(
        path.display().to_string(),
        "sha256",
        format!(
            "is {actual}, but {} recorded {expected} when it was saved: the weights were \
             changed or corrupted since",
            record.display()
        ),
    ))
}

/// The digest recorded for `path` and the file that records it.
fn recorded(path: &Path) -> Result<Option<(String, PathBuf)>> {
    let folder = path.parent().unwrap_or(Path::new("."));
    let Some(name) = path.file_name().and_then(|n| n.to_str()) else {
        return Ok(None);
    };
    let checkpoint = if folder.join(STATE).is_file() {
        Some(folder.to_path_buf())
    } else if name == POLICY {
        latest(folder)?
    } else {
        None
    };
    if let Some(dir) = checkpoint {
        let state = read_state(&dir)?;
        return Ok(state
            .checksums
            .get(name)
            .map(|digest| (digest.clone(), dir.join(STATE))));
    }
    if name != POLICY {
        return Ok(None);
    }
    let averaged = folder.join("averaged.json");
    if averaged.is_file()
        && let Some(found) = averaged_digest(&averaged)?
    {
        return Ok(Some(found));
    }
    let card = folder.join("CARD.md");
    if card.is_file() {
        return card_digest(&card);
    }
    Ok(None)
}

/// The `policy_sha256` of an `averaged.json` (absent in one written before it was kept).
fn averaged_digest(path: &Path) -> Result<Option<(String, PathBuf)>> {
    let text = crate::io::read_text(path, crate::io::Format::Settings)?;
    let value: serde_json::Value = crate::io::parse_json(&text, &path.display().to_string())?;
    let Some(field) = value.get("policy_sha256") else {
        return Ok(None);
    };
    let digest = field.as_str().filter(|d| is_digest(d)).ok_or_else(|| {
        Error::invalid(
            path.display().to_string(),
            "policy_sha256",
            format!("is {field}; expected 64 lowercase hex digits"),
        )
    })?;
    Ok(Some((digest.to_string(), path.to_path_buf())))
}

/// The digest of a model card's weights line, if it has one.
fn card_digest(path: &Path) -> Result<Option<(String, PathBuf)>> {
    let text = crate::io::read_text(path, crate::io::Format::Settings)?;
    let Some((k, line)) = text
        .lines()
        .enumerate()
        .find(|(_, l)| l.contains(CARD_WEIGHTS))
    else {
        return Ok(None);
    };
    let start = line.find(CARD_WEIGHTS).unwrap_or(0) + CARD_WEIGHTS.len();
    let digest = line[start..].split('`').next().unwrap_or("");
    if !is_digest(digest) {
        return Err(Error::invalid(
            path.display().to_string(),
            format!("line {}", k + 1),
            format!(
                "the weights' sha256 is `{digest}`; expected 64 lowercase hex digits after \
                 {CARD_WEIGHTS}"
            ),
        ));
    }
    Ok(Some((digest.to_string(), path.to_path_buf())))
}

fn is_digest(text: &str) -> bool {
    text.len() == 64 && text.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn card_line(digest: &str) -> String {
        format!("# A model\n\n**Weights:** {CARD_WEIGHTS}{digest}` (checked).\n")
    }

    #[test]
    fn a_model_folders_weights_are_checked_against_its_card_or_average_record() {
        let dir = tempfile::tempdir().expect("temp dir");
        let policy = dir.path().join(POLICY);
        let weights = b"trained weights".to_vec();
        std::fs::write(dir.path().join("CARD.md"), card_line(&sha256_hex(&weights)))
            .expect("write");
        verify(&policy, &weights).expect("as recorded");
        let err = verify(&policy, b"changed weights")
            .expect_err("changed since")
            .to_string();
        assert!(
            err.contains("CARD.md recorded") && err.contains("changed"),
            "{err}"
        );
        // An average's own record comes first.
        let other = sha256_hex(b"averaged weights");
        std::fs::write(
            dir.path().join("averaged.json"),
            format!("{{\"method\": \"RL\", \"sources\": [], \"policy_sha256\": \"{other}\"}}"),
        )
        .expect("write");
        verify(&policy, b"averaged weights").expect("the average's record");
        let err = verify(&policy, &weights)
            .expect_err("not the average")
            .to_string();
        assert!(err.contains("averaged.json recorded"), "{err}");
        // A record that is no digest is an error of its file, not a silent pass.
        std::fs::remove_file(dir.path().join("averaged.json")).expect("remove");
        std::fs::write(dir.path().join("CARD.md"), card_line("abc")).expect("write");
        let err = verify(&policy, &weights)
            .expect_err("malformed")
            .to_string();
        assert!(
            err.contains("CARD.md: line 3") && err.contains("64 lowercase hex"),
            "{err}"
        );
        // A folder of the user's without a record is not checked; nor is a value network.
        std::fs::write(dir.path().join("CARD.md"), "# notes\n").expect("write");
        verify(&policy, b"anything").expect("no record");
        std::fs::write(dir.path().join("CARD.md"), card_line(&sha256_hex(&weights)))
            .expect("write");
        verify(&dir.path().join("value.bpk"), b"anything").expect("the card is the policy's");
    }
}
