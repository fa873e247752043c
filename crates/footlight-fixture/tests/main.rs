//! Integration tests of footlight-fixture, one binary (one link) with a
//! module per area.

mod cases;
