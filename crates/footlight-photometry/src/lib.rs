//! Photometry for Footlight (being built).
