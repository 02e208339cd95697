//! Settings that are gone, kept by name so that an old spec or `--set` naming one is told what became of it.

/// Settings that were removed, with what replaced them: an old spec naming one gets this reason instead of a
/// bare "unknown field".
pub const REMOVED: &[(&str, &str)] = &[
    (
        "projection_order",
        "the shape projection follows the last stretch pass (the other orders measured worse)",
    ),
    (
        "operator_block",
        "every frame is positioned with its own operator (a shared one measured no faster)",
    ),
    (
        "flattening",
        "patches are unfolded, with LSCM where one folds over (LSCM everywhere measured slower and no better)",
    ),
    (
        "contrast_thresholds",
        "the Canny thresholds hold at every radius (dividing them by the radius measured worse)",
    ),
    (
        "fold_restore",
        "replaced by the relief (`deform.relief.*`), which measures the capture instead of assuming its filter",
    ),
    ("all_views", "replaced by `views = \"all\"`"),
    (
        "cover_views",
        "replaced by `views = \"cover\"` (true) or `views = \"front-back\"` (false)",
    ),
];

/// The reason a removed field is gone, for an error message about `field`.
pub fn removed(field: &str) -> Option<&'static str> {
    let last = field.rsplit('.').next().unwrap_or(field);
    REMOVED
        .iter()
        .find(|(f, _)| *f == last)
        .map(|(_, why)| *why)
}
