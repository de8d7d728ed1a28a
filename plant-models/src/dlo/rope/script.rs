//! Scripted hands (placeholder, filled in below).
