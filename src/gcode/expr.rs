//! RS274 expressions and parameters (being written).
