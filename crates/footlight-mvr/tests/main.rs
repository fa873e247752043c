//! footlight-mvr tests: known answers from the generator, the Python peers
//! (pygdtf, pymvr), refused archives and bounded fuzzing.

mod cases;
