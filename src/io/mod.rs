//! Files and terminals: what an input file holds (by its content, [`content`]), CSV tables with
//! positioned errors, atomic output, progress bars, plots, truth files for the heading
//! benchmark, and recordings (MCAP: [`recording`]). ROS 2 bags are ROS 2's room
//! (`transport::ros2::bag`), built on [`mcap_file`] and [`atomic`].
//!
//! Nothing in the maths modules (`wavelet`, `allan`, ...) touches this; the commands do.
//!
//! The files stand in layers, none importing another that imports it back: the errors of a bad
//! input file ([`InputError`], and a bag's `BagError`, in `error.rs`) and `atomic` at the
//! ground; the sniffer ([`content`]); MCAP opening ([`mcap_file`]) and the CSV reader above
//! it; the reader of recordings on [`mcap_file`]; truth files on top.

pub mod atomic;
pub mod content;
mod csv_fast;
pub mod csv_table;
mod error;
pub mod mcap_file;
pub mod model_file;
pub mod plot;
pub mod progress;
pub mod recording;
pub mod truth;

pub use csv_table::{
    read_table, read_table_keeping_time, read_table_reference, write_table, write_table_with_time,
    RowRead, RowReader, Table, TimeColumn, TIME_COLUMNS,
};
pub use error::{BagError, BagErrorKind, InputError};
