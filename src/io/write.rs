//! Writing files whole: the parent folder made, the bytes flushed, and no partial file left
//! behind where writing failed (a full disk, a vanished folder), where a half-written image or
//! mesh would have looked like a result.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

/// Create `path` (and its missing parent folders), let `write` fill it through a buffer, and
/// flush it. When any step fails the file is removed again, if the path names a regular file
/// (not a link, device or pipe), and the first error is returned.
pub fn write_whole(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> std::io::Result<()> {
    if let Some(dir) = path.parent().filter(|dir| !dir.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)?;
    }
    let mut out = BufWriter::new(File::create(path)?);
    let written = write(&mut out).and_then(|()| out.flush());
    drop(out);
    if written.is_err()
        && std::fs::symlink_metadata(path).is_ok_and(|metadata| metadata.file_type().is_file())
    {
        // The write's own error is the one to report; a failure to remove adds nothing to it.
        let _ = std::fs::remove_file(path);
    }
    written
}

/// Make the folder `dir` (and its missing parents) for a command's outputs. A file already
/// there under that name is refused by saying so, where the system would only say "File exists".
pub fn output_folder(dir: &Path) -> crate::error::Result<()> {
    if std::fs::metadata(dir).is_ok_and(|metadata| !metadata.is_dir()) {
        return Err(crate::error::Error::Usage(format!(
            "-o {}: a file of that name is there; name a folder for the outputs (made if missing)",
            dir.display()
        )));
    }
    std::fs::create_dir_all(dir).map_err(|e| crate::error::Error::io(dir, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failed_write_leaves_no_file_and_reports_its_error() {
        let dir = std::env::temp_dir().join(format!("streak-write-{}", std::process::id()));
        let path = dir.join("nested").join("half.txt");
        let error = write_whole(&path, |out| {
            out.write_all(b"first half")?;
            out.flush()?;
            assert!(
                path.is_file(),
                "the bytes reach the file before the failure"
            );
            Err(std::io::Error::other("the second half failed"))
        })
        .unwrap_err();
        assert_eq!(error.to_string(), "the second half failed");
        assert!(!path.exists(), "a partial file was left behind");

        write_whole(&path, |out| out.write_all(b"whole")).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"whole");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
