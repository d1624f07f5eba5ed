//! Order statistics shared across the stages: the median, taken the one way everywhere
//! (perception's riser fronts, planning's usual rise, the clock's anchor, the benchmarks).

/// The median of `values` (the upper one of an even count), `None` when there are none.
/// NaNs order after every number (`f64::total_cmp`).
pub fn median(values: impl IntoIterator<Item = f64>) -> Option<f64> {
    let mut v: Vec<f64> = values.into_iter().collect();
    if v.is_empty() {
        return None;
    }
    let k = v.len() / 2;
    v.select_nth_unstable_by(k, f64::total_cmp);
    Some(v[k])
}

#[cfg(test)]
mod tests {
    use super::median;

    #[test]
    fn the_median_is_the_middle_value_and_the_upper_of_an_even_count() {
        assert_eq!(median([0.3, 0.1, 0.2]), Some(0.2));
        assert_eq!(median([0.4, 0.1, 0.3, 0.2]), Some(0.3));
        assert_eq!(median([5.0]), Some(5.0));
        assert_eq!(median(std::iter::empty()), None);
        // A NaN sorts last: it moves the median by one place, never panics.
        assert_eq!(median([f64::NAN, 1.0, 2.0]), Some(2.0));
    }
}
