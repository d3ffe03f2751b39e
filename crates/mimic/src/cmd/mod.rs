//! One module per subcommand.

pub mod bench;
pub mod eval;
pub mod import;
pub mod info;
pub mod morph;
pub mod render;
pub mod replay;
pub mod rig;
pub mod rig_check;
pub mod rig_export;
pub mod rig_new;
pub mod send;
pub mod serve;
pub mod setup;
pub mod view;
pub mod worker;
