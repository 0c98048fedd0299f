//! The viewer's integration tests: the pages in a real browser.

mod browser;
