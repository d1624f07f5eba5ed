//! Sharding a suite over machines an existing engine starts (a CI matrix, a Slurm array, a
//! Kubernetes Indexed Job): shard `M/N` (1-based, as cargo-nextest's partitions) runs the
//! cases whose id hashes to `M - 1` modulo `N`, so a case stays in its shard when the suite
//! grows; and the merge of the shards' results, which fails when a run is missing or twice.

use super::results::CaseResult;
use super::suite::fnv1a;
use std::collections::BTreeMap;
use std::fmt;

/// One shard of `total` (1-based `index`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// Which (1-based).
    pub index: usize,
    /// Of how many.
    pub total: usize,
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.total)
    }
}

/// Why a shard could not be chosen, or shards not merged.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ShardError {
    /// `--shard` or an environment variable is malformed.
    #[error("shard {given:?} ({source_of}): {reason}")]
    Bad {
        /// What was given.
        given: String,
        /// Where it came from.
        source_of: String,
        /// What is wrong.
        reason: String,
    },
    /// The results come from different suites (or versions of one).
    #[error("the results are not of one suite: {0}")]
    Mixed(String),
    /// Runs missing from the merge.
    #[error("{count} runs missing from the shards, e.g. {examples}")]
    Missing {
        /// How many.
        count: usize,
        /// A few of them.
        examples: String,
    },
    /// Runs in more than one shard (or twice in one).
    #[error("{count} runs appear more than once, e.g. {examples}")]
    Duplicated {
        /// How many.
        count: usize,
        /// A few of them.
        examples: String,
    },
}

impl Shard {
    /// `M/N`, 1 <= M <= N.
    pub fn parse(text: &str, source_of: &str) -> Result<Self, ShardError> {
        let bad = |reason: &str| ShardError::Bad {
            given: text.into(),
            source_of: source_of.into(),
            reason: reason.into(),
        };
        let (m, n) = text.split_once('/').ok_or_else(|| bad("expected M/N, e.g. 2/4"))?;
        let index: usize = m.trim().parse().map_err(|_| bad("M is not a whole number"))?;
        let total: usize = n.trim().parse().map_err(|_| bad("N is not a whole number"))?;
        Self::new(index, total).ok_or_else(|| bad("needs 1 <= M <= N"))
    }

    /// Shard `index` of `total` when 1 <= index <= total.
    pub fn new(index: usize, total: usize) -> Option<Self> {
        (index >= 1 && index <= total).then_some(Self { index, total })
    }

    /// Whether this shard runs case `id`.
    pub fn owns(&self, id: &str) -> bool {
        (fnv1a(id.as_bytes()) % self.total as u64) as usize == self.index - 1
    }

    /// The shard the environment names, if one does: GitLab's parallel jobs
    /// (`CI_NODE_INDEX`/`CI_NODE_TOTAL`, 1-based), a Slurm job array
    /// (`SLURM_ARRAY_TASK_ID` with `SLURM_ARRAY_TASK_MIN`/`SLURM_ARRAY_TASK_COUNT`), a
    /// Kubernetes Indexed Job (`JOB_COMPLETION_INDEX`, 0-based, with `shards` from
    /// `--shards N`). `var` reads a variable (the process environment, or a test's).
    pub fn from_env(
        var: &dyn Fn(&str) -> Option<String>,
        shards: Option<usize>,
    ) -> Result<Option<Self>, ShardError> {
        let num = |name: &str| -> Result<Option<usize>, ShardError> {
            match var(name) {
                None => Ok(None),
                Some(v) => v.trim().parse().map(Some).map_err(|_| ShardError::Bad {
                    given: v.clone(),
                    source_of: name.into(),
                    reason: "not a whole number".into(),
                }),
            }
        };
        let bad = |given: String, source_of: &str, reason: &str| ShardError::Bad {
            given,
            source_of: source_of.into(),
            reason: reason.into(),
        };
        if let (Some(i), Some(n)) = (num("CI_NODE_INDEX")?, num("CI_NODE_TOTAL")?) {
            return Self::new(i, n).map(Some).ok_or_else(|| {
                bad(format!("{i}/{n}"), "CI_NODE_INDEX/CI_NODE_TOTAL", "needs 1 <= index <= total")
            });
        }
        if let Some(id) = num("SLURM_ARRAY_TASK_ID")? {
            let min = num("SLURM_ARRAY_TASK_MIN")?.unwrap_or(0);
            let count = num("SLURM_ARRAY_TASK_COUNT")?.ok_or_else(|| {
                bad(id.to_string(), "SLURM_ARRAY_TASK_ID", "SLURM_ARRAY_TASK_COUNT is not set")
            })?;
            let index = id.checked_sub(min).map(|k| k + 1).unwrap_or(0);
            return Self::new(index, count).map(Some).ok_or_else(|| {
                bad(format!("{id} (min {min}, count {count})"), "SLURM_ARRAY_TASK_ID", "outside the array")
            });
        }
        if let Some(k) = num("JOB_COMPLETION_INDEX")? {
            let n = shards.ok_or_else(|| {
                bad(k.to_string(), "JOB_COMPLETION_INDEX", "give the job's completions with --shards N")
            })?;
            return Self::new(k + 1, n)
                .map(Some)
                .ok_or_else(|| bad(format!("{k} of {n}"), "JOB_COMPLETION_INDEX", "needs 0 <= index < N"));
        }
        Ok(None)
    }
}

/// The shards' results as one: every run of the suite exactly once, ordered by case and draw.
pub fn merge(parts: Vec<Vec<CaseResult>>) -> Result<Vec<CaseResult>, ShardError> {
    let all: Vec<CaseResult> = parts.into_iter().flatten().collect();
    let Some(first) = all.first() else {
        return Err(ShardError::Missing { count: 0, examples: "every run (no results)".into() });
    };
    let (suite, hash, total, seeds) =
        (first.suite.clone(), first.suite_hash.clone(), first.cases_total, first.seeds);
    if let Some(other) = all
        .iter()
        .find(|r| r.suite != suite || r.suite_hash != hash || r.cases_total != total || r.seeds != seeds)
    {
        return Err(ShardError::Mixed(format!(
            "{} (hash {}, {} cases x {} draws) and {} (hash {}, {} cases x {} draws)",
            suite, hash, total, seeds, other.suite, other.suite_hash, other.cases_total, other.seeds
        )));
    }
    let mut by_key: BTreeMap<(usize, usize), Vec<CaseResult>> = BTreeMap::new();
    for r in all {
        by_key.entry((r.index, r.seed_index)).or_default().push(r);
    }
    let show = |keys: &[(usize, usize)]| {
        keys.iter().take(5).map(|(i, k)| format!("{suite}-{i:04} draw {k}")).collect::<Vec<_>>().join(", ")
    };
    let twice: Vec<(usize, usize)> = by_key.iter().filter(|(_, v)| v.len() > 1).map(|(k, _)| *k).collect();
    if !twice.is_empty() {
        return Err(ShardError::Duplicated { count: twice.len(), examples: show(&twice) });
    }
    let missing: Vec<(usize, usize)> = (0..total)
        .flat_map(|i| (0..seeds).map(move |k| (i, k)))
        .filter(|k| !by_key.contains_key(k))
        .collect();
    if !missing.is_empty() {
        return Err(ShardError::Missing { count: missing.len(), examples: show(&missing) });
    }
    Ok(by_key.into_values().flatten().collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_partition_the_ids_and_a_case_keeps_its_shard() {
        let ids: Vec<String> = (0..500).map(|i| format!("ci-{i:04}")).collect();
        let shards: Vec<Shard> = (1..=4).map(|m| Shard::new(m, 4).expect("valid")).collect();
        for id in &ids {
            assert_eq!(shards.iter().filter(|s| s.owns(id)).count(), 1, "{id}");
        }
        let sizes: Vec<usize> = shards.iter().map(|s| ids.iter().filter(|i| s.owns(i)).count()).collect();
        assert!(sizes.iter().all(|&n| n > 90), "roughly even: {sizes:?}");
        assert_eq!(Shard::parse("2/4", "--shard"), Ok(shards[1]));
        assert!(Shard::parse("5/4", "--shard").is_err());
        assert!(Shard::parse("0/4", "--shard").is_err());
        assert!(Shard::parse("two", "--shard").is_err());
    }

    #[test]
    fn the_shard_is_read_from_gitlab_slurm_and_kubernetes() {
        let env = |pairs: &'static [(&'static str, &'static str)]| {
            move |k: &str| pairs.iter().find(|(n, _)| *n == k).map(|(_, v)| v.to_string())
        };
        let gitlab = env(&[("CI_NODE_INDEX", "3"), ("CI_NODE_TOTAL", "5")]);
        assert_eq!(Shard::from_env(&gitlab, None), Ok(Shard::new(3, 5)));
        let slurm = env(&[
            ("SLURM_ARRAY_TASK_ID", "11"),
            ("SLURM_ARRAY_TASK_MIN", "10"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
        ]);
        assert_eq!(Shard::from_env(&slurm, None), Ok(Shard::new(2, 4)));
        let k8s = env(&[("JOB_COMPLETION_INDEX", "0")]);
        assert_eq!(Shard::from_env(&k8s, Some(3)), Ok(Shard::new(1, 3)));
        assert!(Shard::from_env(&k8s, None).is_err(), "Kubernetes needs --shards");
        assert_eq!(Shard::from_env(&env(&[]), None), Ok(None));
        assert!(Shard::from_env(&env(&[("CI_NODE_INDEX", "x"), ("CI_NODE_TOTAL", "2")]), None).is_err());
    }
}
