//! How a build tells its progress.

/// Follows a build: phases with a total of work units, and progress within them.
pub trait Report: Sync {
    fn phase(&self, name: &'static str, total: u64);
    fn advance(&self, n: u64);
}

/// A [`Report`] that says nothing.
pub struct Silent;
impl Report for Silent {
    fn phase(&self, _: &'static str, _: u64) {}
    fn advance(&self, _: u64) {}
}
