//! Where a run came from: the build and the CPU that made it (in every record's
//! [`crate::record::Provenance`]).

/// The git commit and version this binary was built from.
pub fn build_id() -> String {
    format!(
        "mrdrive {} ({})",
        env!("CARGO_PKG_VERSION"),
        option_env!("MRDRIVE_GIT_COMMIT").unwrap_or("unknown commit")
    )
}

/// The CPU's model name (the first `model name` of `/proc/cpuinfo`), or `None` where
/// the OS does not say. Run records carry it ([`Provenance::cpu`]).
pub fn cpu_model() -> Option<String> {
    cpuinfo_field(
        &std::fs::read_to_string("/proc/cpuinfo").ok()?,
        "model name",
    )
}

/// The first value of `key` in a `/proc/cpuinfo` text (`key<tabs>: value`), trimmed;
/// `None` if absent or blank.
fn cpuinfo_field(cpuinfo: &str, key: &str) -> Option<String> {
    cpuinfo
        .lines()
        .find_map(|l| l.strip_prefix(key)?.trim_start().strip_prefix(':'))
        .map(|value| value.trim().to_string())
        .filter(|value| !value.is_empty())
}

#[cfg(test)]
mod tests {
    use super::cpuinfo_field;

    #[test]
    fn a_cpuinfo_field_is_its_first_value() {
        let info = "processor\t: 0\nvendor_id\t: AuthenticAMD\nmodel\t\t: 17\n\
                    model name\t: AMD EPYC 9R14\nprocessor\t: 1\nmodel name\t: other\n";
        let field = |key| cpuinfo_field(info, key);
        assert_eq!(field("model name").as_deref(), Some("AMD EPYC 9R14"));
        assert_eq!(field("vendor_id").as_deref(), Some("AuthenticAMD"));
        // `model` is its own key, not the start of `model name`.
        let named_first = "model name\t: AMD EPYC 9R14\nmodel\t\t: 17\n";
        assert_eq!(cpuinfo_field(named_first, "model").as_deref(), Some("17"));
        // A blank value or none at all says nothing.
        assert_eq!(cpuinfo_field("model name\t:   \n", "model name"), None);
        assert_eq!(cpuinfo_field("", "vendor_id"), None);
    }
}
