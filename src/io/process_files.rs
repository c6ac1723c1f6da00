//! The kernel's files about this process (`/proc/self/...`), for [`crate::usage`]. They are
//! not user input or output (the kernel makes them up on each read and reports size 0), so
//! they bypass the opener's checks; they live here so that every file access of rtr is in
//! this module.

/// The text of `/proc/self/<name>`, or `None` where there is none (not Linux).
pub fn read_process_file(name: &str) -> Option<String> {
    std::fs::read_to_string(format!("/proc/self/{name}")).ok()
}

/// Writes `text` to `/proc/self/<name>`; ignored where that is not possible.
pub fn write_process_file(name: &str, text: &str) {
    let _ = std::fs::write(format!("/proc/self/{name}"), text);
}
