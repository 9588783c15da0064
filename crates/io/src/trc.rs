//! (being written)
/// Temporary.
pub fn read_trc_path(_p: &std::path::Path) -> crate::Result<locap_core::Take> {
    Err(crate::Error::Unsupported("TRC".into()))
}
