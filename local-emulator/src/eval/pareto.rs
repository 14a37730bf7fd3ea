//! The Pareto front of (time, error) points: the settings no other setting beats on both.

/// For each point `(seconds, error)`, whether it is on the front: no other point has both
/// `seconds` and `error` at most its own and one of them strictly less. Equal points are all on
/// the front. Points with a NaN coordinate are never on it. O(n^2), deterministic.
pub fn pareto_front(points: &[(f64, f64)]) -> Vec<bool> {
    points
        .iter()
        .map(|&(t, e)| {
            !t.is_nan()
                && !e.is_nan()
                && !points
                    .iter()
                    .any(|&(t2, e2)| t2 <= t && e2 <= e && (t2 < t || e2 < e))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::pareto_front;

    #[test]
    fn dominated_points_are_off_the_front() {
        let points = [
            (1.0, 0.5),  // front: fastest
            (2.0, 0.4),  // front
            (3.0, 0.45), // dominated by (2.0, 0.4)
            (4.0, 0.1),  // front: most accurate
            (4.0, 0.2),  // dominated by (4.0, 0.1): same time, more error
        ];
        assert_eq!(pareto_front(&points), vec![true, true, false, true, false]);
    }

    #[test]
    fn equal_points_are_both_on_the_front_and_nan_never() {
        let points = [(1.0, 1.0), (1.0, 1.0), (f64::NAN, 0.0), (0.5, f64::NAN)];
        assert_eq!(pareto_front(&points), vec![true, true, false, false]);
    }
}
