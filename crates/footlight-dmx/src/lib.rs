//! DMX input for Footlight (being built).
