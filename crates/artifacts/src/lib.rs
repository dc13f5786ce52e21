//! Every stage's outputs: numbers checked finite before they are written, files written all
//! or none (staged beside their destination, fsynced, renamed, the folder fsynced), and
//! outputs that would replace an input refused.
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod plausible;

use std::io::Write;
use std::path::Path;

/// Refuses a command line whose outputs would replace one of its inputs or each other
/// (`identify --log run.csv -o run.csv` would destroy the log): an output that exists is
/// compared with every existing input by canonical path. Names both paths.
pub fn refuse_outputs_that_are_inputs(inputs: &[&Path], outputs: &[&Path]) -> anyhow::Result<()> {
    let canonical = |p: &Path| std::fs::canonicalize(p).ok();
    for (k, out) in outputs.iter().enumerate() {
        let Some(o) = canonical(out) else { continue };
        for input in inputs {
            if canonical(input).as_ref() == Some(&o) {
                anyhow::bail!(
                    "output {} is the input {}: refusing to replace an input",
                    out.display(),
                    input.display()
                );
            }
        }
        for other in &outputs[..k] {
            if canonical(other).as_ref() == Some(&o) {
                anyhow::bail!(
                    "outputs {} and {} are the same file",
                    other.display(),
                    out.display()
                );
            }
        }
    }
    Ok(())
}

/// An error naming `what` and the first value when any of `values` is NaN or infinite:
/// every number a command writes passes this check first (JSON would write NaN as
/// `null`, CSV as `NaN`).
pub fn ensure_finite(what: &str, values: impl IntoIterator<Item = f64>) -> anyhow::Result<()> {
    match values.into_iter().enumerate().find(|(_, v)| !v.is_finite()) {
        Some((k, v)) => anyhow::bail!("{what}: value {} is {v}, not a finite number", k + 1),
        None => Ok(()),
    }
}

/// Writes several outputs all or none: every one is staged in a temporary file beside its
/// destination (non-regular destinations refused, as in [`write_atomic`]), written and
/// fsynced before any is renamed into place, so a failure while preparing them leaves
/// every output as it was; after the renames each destination folder is fsynced, so the
/// new names survive a power cut. Files get the usual `0666` less the process umask.
pub fn write_atomic_all(files: &[(&Path, &[u8])]) -> anyhow::Result<()> {
    let mut staged = Vec::with_capacity(files.len());
    for (path, bytes) in files {
        staged.push((path, stage(path, bytes)?));
    }
    let mut dirs: Vec<&Path> = Vec::new();
    for (path, tmp) in staged {
        tmp.persist(path).map_err(|e| {
            anyhow::anyhow!("{}: cannot rename into place: {}", path.display(), e.error)
        })?;
        let dir = parent_dir(path);
        if !dirs.contains(&dir) {
            dirs.push(dir);
        }
    }
    for dir in dirs {
        sync_dir(dir)?;
    }
    Ok(())
}

/// Writes `bytes` to `path` via a temporary file in the same directory and a rename:
/// either the whole new content is there, or the old state is untouched.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    write_atomic_all(&[(path, bytes)])
}

/// The folder `path` is in (`.` for a bare file name).
fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Makes the renames in `dir` durable (a no-op where folders cannot be opened).
fn sync_dir(dir: &Path) -> anyhow::Result<()> {
    #[cfg(unix)]
    std::fs::File::open(dir)
        .and_then(|d| d.sync_all())
        .map_err(|e| anyhow::anyhow!("{}: cannot sync the folder: {e}", dir.display()))?;
    #[cfg(not(unix))]
    let _ = dir;
    Ok(())
}

/// `bytes` in a synced temporary file beside `path` (mode `0666` less the umask, like any
/// file the user creates), ready to be renamed onto it.
fn stage(path: &Path, bytes: &[u8]) -> anyhow::Result<tempfile::NamedTempFile> {
    // Renaming over a device, a directory or a pipe would replace it (`-o /dev/null`
    // once replaced the system's null device with a file): only regular files.
    if let Ok(meta) = std::fs::metadata(path)
        && !meta.is_file()
    {
        anyhow::bail!(
            "{}: exists and is not a regular file; refusing to replace it",
            path.display()
        );
    }
    let dir = parent_dir(path);
    let mut builder = tempfile::Builder::new();
    // The temporary file would be created 0600; asking for 0666 lets the umask decide.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let mut tmp = builder.tempfile_in(dir).map_err(|e| {
        anyhow::anyhow!(
            "{}: cannot create a temporary file in {}: {e}",
            path.display(),
            dir.display()
        )
    })?;
    tmp.write_all(bytes)
        .and_then(|_| tmp.as_file().sync_all())
        .map_err(|e| anyhow::anyhow!("{}: write failed: {e}", path.display()))?;
    Ok(tmp)
}
