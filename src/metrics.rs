//! Quality measures of a tracking result (method.md §6, §8).
