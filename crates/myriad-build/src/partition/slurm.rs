//! The Slurm driver (`myriad slurm`): a plan's scatter tasks (where parts share LAZ chunks),
//! its parts and its merge submitted as jobs with `sbatch`, each after the one before it
//! succeeded, and, where asked, waited for through `scontrol`'s job states, naming the tasks
//! that failed and their logs.

use super::BuildPlan;
use myriad_core::{Error, Result};
use std::path::{Path, PathBuf};
use std::process::Command;

/// A build in parts to submit.
pub struct SlurmBuild {
    /// The plan (`myriad plan`), as the compute nodes see it.
    pub plan: PathBuf,
    /// The dataset the merge writes.
    pub output: PathBuf,
    /// Where the parts go.
    pub parts: PathBuf,
    /// The myriad program as the compute nodes see it.
    pub myriad: PathBuf,
    /// Whether the chunks several parts read are decompressed once by scatter tasks first.
    pub exchange: bool,
    /// Options for every sbatch call.
    pub sbatch: Vec<String>,
}

/// The jobs submitted: their ids (with a dry run, the shell variables holding them).
pub struct Submitted {
    pub scatter: Option<String>,
    pub parts: String,
    pub merge: String,
    /// The number of parts (array tasks of each array job).
    pub tasks: usize,
}

/// Submits jobs, or with `dry_run` writes the shell lines that would (`lines`).
pub struct Sbatch {
    pub dry_run: bool,
    pub lines: Vec<String>,
}

/// A word for `sh -c`, quoted where it has to be.
pub fn sh_quote(s: &str) -> String {
    let plain = |c: char| c.is_ascii_alphanumeric() || "_-=:/.,%+@".contains(c);
    if !s.is_empty() && s.chars().all(plain) {
        return s.to_string();
    }
    format!("'{}'", s.replace('\'', "'\\''"))
}

impl Sbatch {
    /// Submits a job and returns its id; with a dry run, writes the command as a shell line
    /// instead, setting the shell variable `var` (when not empty) to the job's id, and returns
    /// `$VAR` for the lines after it (an argument ending in `$NAME` is left unquoted there).
    fn submit(&mut self, args: &[String], var: &str) -> Result<String> {
        if self.dry_run {
            let words: Vec<String> = (args.iter())
                .map(|a| match a.rfind('$') {
                    Some(at)
                        if a.len() > at + 1
                            && a[at + 1..].chars().all(|c| c.is_ascii_uppercase()) =>
                    {
                        format!("{}{}", sh_quote(&a[..at]), &a[at..])
                    }
                    _ => sh_quote(a),
                })
                .collect();
            let line = format!("sbatch --parsable {}", words.join(" "));
            self.lines.push(if var.is_empty() {
                line
            } else {
                format!("{var}=$({line})")
            });
            return Ok(format!("${var}"));
        }
        let out = (Command::new("sbatch").arg("--parsable").args(args).output()).map_err(|e| {
            Error::Invalid(format!(
                "sbatch: is Slurm installed and SLURM_CONF set? ({e})"
            ))
        })?;
        if !out.status.success() {
            let why = String::from_utf8_lossy(&out.stderr);
            return Err(Error::Invalid(format!("sbatch: {}", why.trim())));
        }
        let id = String::from_utf8_lossy(&out.stdout);
        // "--parsable" prints "id" or "id;cluster".
        Ok(id.trim().split(';').next().unwrap_or("").to_string())
    }
}

/// Submits `b`'s jobs: the scatter array job (where the plan has chunked inputs and `b`
/// exchanges), the parts' array job after it, and the merge after every part succeeded.
pub fn submit(plan: &BuildPlan, b: &SlurmBuild, sbatch: &mut Sbatch) -> Result<Submitted> {
    let q = |p: &Path| sh_quote(&p.display().to_string());
    let n = plan.parts.len();
    let exchange = b.exchange && !plan.chunked.is_empty();
    // An array job of one task per part, after `after` succeeded where given.
    let mut array_job = |name: &str, log: &str, after: Option<&str>, command: &str, var: &str| {
        let mut args = vec![
            format!("--job-name=myriad-{name}"),
            format!("--array=0-{}", n - 1),
            format!("--output={}/{log}%A_%a.out", b.parts.display()),
        ];
        if let Some(job) = after {
            args.push(format!("--dependency=afterok:{job}"));
            args.push("--kill-on-invalid-dep=yes".to_string());
        }
        args.extend(b.sbatch.iter().cloned());
        args.push(format!(
            "--wrap=exec {} convert --plan {} {command} -o {}",
            q(&b.myriad),
            q(&b.plan),
            q(&b.parts)
        ));
        sbatch.submit(&args, var)
    };
    let scatter = if exchange {
        let job = array_job(
            "scatter",
            "slurm-scatter-",
            None,
            "--scatter auto",
            "SCATTER",
        )?;
        Some(job)
    } else {
        None
    };
    let command = format!("--part auto{}", if exchange { " --exchanged" } else { "" });
    let parts = array_job("part", "slurm-", scatter.as_deref(), &command, "PARTS")?;
    let mut merge = vec![
        "--job-name=myriad-merge".to_string(),
        format!("--dependency=afterok:{parts}"),
        "--kill-on-invalid-dep=yes".to_string(),
        format!("--output={}/slurm-merge-%j.out", b.parts.display()),
    ];
    merge.extend(b.sbatch.iter().cloned());
    merge.push(format!(
        "--wrap=exec {} merge {} {} -o {} --force",
        q(&b.myriad),
        q(&b.plan),
        q(&b.parts),
        q(&b.output)
    ));
    let merge = sbatch.submit(&merge, "")?;
    Ok(Submitted {
        scatter,
        parts,
        merge,
        tasks: n,
    })
}

/// A task's state in Slurm's words, (array index or none, state, exit code).
type TaskState = (Option<String>, String, String);

/// The tasks of job `id`, from `scontrol`.
fn job_states(id: &str) -> Result<Vec<TaskState>> {
    let out = (Command::new("scontrol")
        .args(["show", "job", "-o", id])
        .output())
    .map_err(|e| Error::Invalid(format!("scontrol: {e}")))?;
    if !out.status.success() {
        return Err(Error::Invalid(format!(
            "scontrol show job {id}: {}",
            String::from_utf8_lossy(&out.stderr).trim()
        )));
    }
    Ok(String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let get = |k: &str| {
                l.split_whitespace()
                    .find_map(|t| t.strip_prefix(k).map(String::from))
            };
            (
                get("ArrayTaskId="),
                get("JobState=").unwrap_or_default(),
                get("ExitCode=").unwrap_or_default(),
            )
        })
        .collect())
}

/// The states of a job that has not ended.
const RUNNING: [&str; 5] = [
    "PENDING",
    "RUNNING",
    "CONFIGURING",
    "COMPLETING",
    "SUSPENDED",
];

/// Waits for the merge of `jobs`; an error names the scatter tasks and parts that failed and
/// their logs in `parts` (or the merge's log), with `output` not merged.
pub fn wait(jobs: &Submitted, parts: &Path, output: &Path) -> Result<()> {
    // Slurm reports a job cancelled for a failed dependency as ended, not failed (sbatch --wait
    // returns 0): the states tell.
    loop {
        let m = job_states(&jobs.merge)?;
        let state = m.first().map(|t| t.1.clone()).unwrap_or_default();
        if RUNNING.contains(&state.as_str()) {
            std::thread::sleep(std::time::Duration::from_millis(500));
            continue;
        }
        if state == "COMPLETED" {
            return Ok(());
        }
        let mut failed = Vec::new();
        for (job, what, log) in [
            (jobs.scatter.as_deref(), "scatter task", "slurm-scatter-"),
            (Some(jobs.parts.as_str()), "part", "slurm-"),
        ] {
            let Some(job) = job else { continue };
            let ended = (job_states(job)?.into_iter())
                .filter(|t| t.1 != "COMPLETED" && !RUNNING.contains(&t.1.as_str()));
            failed.extend(ended.map(|(i, s, e)| {
                let i = i.unwrap_or_default();
                format!(
                    "{what} {i} {s} (exit {e}; log {}/{log}{job}_{i}.out)",
                    parts.display()
                )
            }));
        }
        let merge = &jobs.merge;
        return Err(Error::Invalid(if failed.is_empty() {
            format!(
                "merge job {merge} {state}: see {}/slurm-merge-{merge}.out",
                parts.display()
            )
        } else {
            format!(
                "{}: not merged, merge job {merge} {state}: {}",
                output.display(),
                failed.join("; ")
            )
        }));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words_are_quoted_for_the_shell_only_where_they_must_be() {
        assert_eq!(sh_quote("--array=0-3"), "--array=0-3");
        assert_eq!(sh_quote("/a b/c"), "'/a b/c'");
        assert_eq!(sh_quote("it's"), "'it'\\''s'");
        assert_eq!(sh_quote(""), "''");
    }
}
