//! The networks' variables in name order, so that the optimiser's order (and its float summation order) never
//! depends on hashing: the same seed trains the same weights.

use candle_nn::VarMap;

pub trait SortedVars {
    fn all_vars_sorted(&self) -> Vec<candle_core::Var>;
}

impl SortedVars for VarMap {
    fn all_vars_sorted(&self) -> Vec<candle_core::Var> {
        let data = match self.data().lock() {
            Ok(d) => d,
            Err(p) => p.into_inner(),
        };
        let mut named: Vec<(&String, &candle_core::Var)> = data.iter().collect();
        named.sort_by(|a, b| a.0.cmp(b.0));
        named.into_iter().map(|(_, v)| v.clone()).collect()
    }
}
