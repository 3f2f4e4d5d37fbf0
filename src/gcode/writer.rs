//! Toolpath model -> G-code text (being written).
