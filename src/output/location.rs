//! Where an output may go: paths resolved, what a run may replace, and the overlap with the
//! campaign (by path and by device and inode).

use super::*;

/// `path` made absolute, symlinks resolved in the part that exists, `.` and `..` removed.
pub(crate) fn resolve(path: &Path) -> std::io::Result<PathBuf> {
    let absolute = std::path::absolute(path)?;
    let mut existing = absolute.as_path();
    let mut rest = Vec::new();
    while std::fs::symlink_metadata(existing).is_err() {
        rest.push(existing.file_name().map(|n| n.to_os_string()));
        existing = existing.parent().unwrap_or(Path::new("/"));
    }
    let mut resolved = existing.canonicalize()?;
    for part in rest.into_iter().rev() {
        match part {
            Some(name) => resolved.push(name),
            None => {
                resolved.pop();
            }
        }
    }
    Ok(resolved)
}

pub(super) fn home_dir() -> Option<PathBuf> {
    std::env::var_os("HOME")
        .filter(|h| !h.is_empty())
        .and_then(|h| PathBuf::from(h).canonicalize().ok())
}

/// `path` may be replaced: absent, an empty folder, or a folder holding the marker and nothing
/// it does not list.
pub(super) fn check_replaceable(path: &Path, what: &str) -> Result<(), OutputError> {
    let refused = |why: &str| OutputError::Refused {
        path: path.to_path_buf(),
        why: format!("{why}{what}"),
    };
    let meta = match std::fs::symlink_metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(OutputError::io(path)(e)),
        Ok(m) => m,
    };
    if meta.file_type().is_symlink() {
        return Err(refused(
            "it is a symbolic link; give the folder it points to, or a new path",
        ));
    }
    if !meta.is_dir() {
        return Err(refused("it is a file, not an output folder"));
    }
    let empty = std::fs::read_dir(path)
        .map_err(OutputError::io(path))?
        .next()
        .is_none();
    if empty {
        return Ok(());
    }
    dbbcal_output(path).map_err(|why| match why {
        Refusal::NoMarker => refused(&format!(
            "the folder exists and {why}; choose a new or empty folder"
        )),
        why => refused(&format!("the folder {why}")),
    })
}

/// (device, inode) of a file or folder, following links.
pub(super) fn identity(path: &Path) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata(path).ok().map(|m| (m.dev(), m.ino()))
}

/// The campaign must not be, hold, or lie inside anything a run on `out` may remove or replace:
/// `OUT`, `OUT.prev` and the partial folders beside them, compared by path (links and `..`
/// resolved) and by (device, inode), which also sees a bind mount or a link to a campaign file.
pub(super) fn check_overlap(
    out: &Path,
    parent: &Path,
    name: &str,
    campaign: &Path,
) -> Result<(), Refusal> {
    let Ok(campaign) = resolve(campaign) else {
        return Ok(()); // ingest names a missing campaign itself
    };
    if out == campaign {
        return Err(Refusal::IsCampaign { campaign });
    } else if out.starts_with(&campaign) {
        return Err(Refusal::InsideCampaign { campaign });
    } else if campaign.starts_with(out) {
        return Err(Refusal::HoldsCampaign { campaign });
    }
    let Some(campaign_id) = identity(&campaign) else {
        return Ok(());
    };
    // OUT inside the campaign through another path (a bind mount of it).
    let mut ancestor = out.parent();
    while let Some(a) = ancestor {
        if identity(a) == Some(campaign_id) {
            return Err(Refusal::InsideCampaignThrough {
                campaign,
                same: a.to_path_buf(),
            });
        }
        ancestor = a.parent();
    }
    // What a run may remove: OUT.prev and partial folders beside OUT (OUT itself was checked).
    let mut removable = vec![
        out.to_path_buf(),
        out.with_file_name(format!("{name}.prev")),
    ];
    let prefix = format!(".{name}.partial-");
    if let Ok(entries) = std::fs::read_dir(parent) {
        for e in entries.flatten() {
            if e.file_name()
                .to_str()
                .is_some_and(|n| n.starts_with(&prefix))
            {
                removable.push(out.with_file_name(e.file_name()));
            }
        }
    }
    for r in &removable[1..] {
        if campaign == *r || campaign.starts_with(r) {
            return Err(Refusal::RemovableHoldsCampaign {
                removable: r.clone(),
                campaign,
            });
        }
    }
    // The campaign folder and its files (links followed), by identity.
    let mut campaign_ids = std::collections::HashMap::new();
    campaign_ids.insert(campaign_id, campaign.clone());
    if let Ok(Some(entries)) = tree_entries(&campaign, 100_000) {
        for rel in entries {
            let p = campaign.join(rel.trim_end_matches('/'));
            if let Some(id) = identity(&p) {
                campaign_ids.entry(id).or_insert(p);
            }
        }
    }
    for r in &removable {
        let Ok(meta) = std::fs::symlink_metadata(r) else {
            continue;
        };
        if !meta.is_dir() {
            continue;
        }
        let mut found = None;
        if let Ok(Some(entries)) = tree_entries(r, 100_000) {
            use std::os::unix::fs::MetadataExt;
            for rel in entries {
                let p = r.join(rel.trim_end_matches('/'));
                let Ok(m) = std::fs::symlink_metadata(&p) else {
                    continue;
                };
                if let Some(c) = campaign_ids.get(&(m.dev(), m.ino())) {
                    found = Some((p, c.clone()));
                    break;
                }
            }
        }
        if let Some((path, part)) = found {
            return Err(Refusal::RemovableHoldsCampaignPart { path, part });
        }
    }
    Ok(())
}
