//! Tests of `src/job/discover.rs`.

use destair::job::discover::*;

#[test]
fn shards_partition_the_cases() {
    let ids: Vec<String> = (0..500).map(|i| format!("case-{i:03}")).collect();
    for n in [1, 2, 3, 7] {
        let mut seen = vec![0; ids.len()];
        for i in 0..n {
            let s = Shard { index: i, count: n };
            for (k, id) in ids.iter().enumerate() {
                seen[k] += s.contains(id) as usize;
            }
        }
        assert!(seen.iter().all(|&c| c == 1));
    }
    assert!(
        Shard::parse("2/2").is_err() && Shard::parse("1/2").is_ok() && Shard::parse("x").is_err()
    );
}

#[test]
fn slurm_ranges_and_lists() {
    let env = |pairs: &'static [(&'static str, &'static str)]| {
        move |k: &str| {
            pairs
                .iter()
                .find(|(n, _)| *n == k)
                .map(|(_, v)| v.to_string())
        }
    };
    // --array=3-11:4 -> tasks 3, 7, 11; task 7 is index 1 of 3.
    let s = Shard::from_slurm(env(&[
        ("SLURM_ARRAY_TASK_ID", "7"),
        ("SLURM_ARRAY_TASK_MIN", "3"),
        ("SLURM_ARRAY_TASK_MAX", "11"),
        ("SLURM_ARRAY_TASK_STEP", "4"),
        ("SLURM_ARRAY_TASK_COUNT", "3"),
    ]))
    .unwrap();
    assert_eq!(s, Shard { index: 1, count: 3 });
    // --array=1,4,10 reports STEP 1, MIN 1, MAX 10, COUNT 3: refused.
    assert!(Shard::from_slurm(env(&[
        ("SLURM_ARRAY_TASK_ID", "4"),
        ("SLURM_ARRAY_TASK_MIN", "1"),
        ("SLURM_ARRAY_TASK_MAX", "10"),
        ("SLURM_ARRAY_TASK_STEP", "1"),
        ("SLURM_ARRAY_TASK_COUNT", "3")
    ]))
    .is_err());
    assert!(Shard::from_slurm(env(&[])).is_err());
    // An ID outside MIN..MAX is refused, not mapped to an empty shard.
    let err = Shard::from_slurm(env(&[
        ("SLURM_ARRAY_TASK_ID", "99"),
        ("SLURM_ARRAY_TASK_MIN", "1"),
        ("SLURM_ARRAY_TASK_MAX", "5"),
        ("SLURM_ARRAY_TASK_COUNT", "5"),
    ]))
    .unwrap_err();
    assert!(err.contains("outside"), "{err}");
    // --array=0-4:2,7 reports MIN 0 MAX 7 STEP 2 COUNT 4 in every task: refused in all.
    for id in ["0", "2", "4", "7"] {
        let vars = [
            ("SLURM_ARRAY_TASK_ID", id),
            ("SLURM_ARRAY_TASK_MIN", "0"),
            ("SLURM_ARRAY_TASK_MAX", "7"),
            ("SLURM_ARRAY_TASK_STEP", "2"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
        ];
        let get = |k: &str| {
            vars.iter()
                .find(|(n, _)| *n == k)
                .map(|(_, v)| v.to_string())
        };
        assert!(Shard::from_slurm(get).is_err(), "task {id}");
    }
}
