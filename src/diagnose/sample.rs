//! Which points the candidates are screened on when a campaign is large: every candidate is
//! fitted once per fold, so its cost grows with the points, while its verdict does not need a
//! million of them — a few thousand points spread over every test say as much about a missing
//! effect as the whole cell's campaign (the noise floor and the residual itself still use every
//! point). The sample keeps each test's visiting order (the blocks of the cross-validation
//! stay contiguous stretches of time) by taking every s-th point of every test.

/// Most points the candidates are screened on.
pub const MAX_SCREENED: usize = 6000;

/// The points kept (indices, in order) and the decision in words; `None` when all are kept.
pub fn subsample(groups: &[usize], max: usize) -> Option<(Vec<usize>, String)> {
    let n = groups.len();
    if n <= max {
        return None;
    }
    let step = n.div_ceil(max);
    let mut taken = vec![0usize; groups.iter().max().map_or(0, |m| m + 1)];
    let mut kept = Vec::with_capacity(max + taken.len());
    for (i, &g) in groups.iter().enumerate() {
        if taken[g] % step == 0 {
            kept.push(i);
        }
        taken[g] += 1;
    }
    let decision = format!(
        "{n} points: the candidates were screened on one point in {step} of each test \
         ({} points, in visiting order); the residual and the noise floor use all of them",
        kept.len()
    );
    Some((kept, decision))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_step_th_point_of_every_test() {
        // 10 points of test 0 and 5 of test 1 interleaved at the end; at most 6: step 3.
        let mut g = vec![0; 10];
        g.extend([1, 0, 1, 1, 1]);
        let (kept, why) = subsample(&g, 6).unwrap();
        // Test 0: its 1st, 4th, 7th, 10th points (indices 0, 3, 6, 9; its 11th, index 11, is
        // skipped); test 1 (indices 10, 12, 13, 14): its 1st and 4th, indices 10 and 14.
        assert_eq!(kept, [0, 3, 6, 9, 10, 14]);
        assert!(
            why.starts_with("15 points") && why.contains("one point in 3 of each test (6 points")
        );
        assert!(subsample(&g, 15).is_none());
    }
}
