//! What the two networks (the LSTM of §3.3 and the cGAN of §4.2) share: seeded initialisation and an Adam
//! whose state can be checkpointed.

pub mod adam;
pub mod seed;
pub mod vars;
