//! Research drivers of crease, kept out of the product crates: each example in `examples/` answers one
//! measurement question (what a kernel costs against its predecessor, where a task's time goes) in one
//! process, alternating the contenders so machine load hits them alike. Run one with
//! `cargo run --release -p crease-research --example NAME -- ARGS`; its doc comment says what it prints.
