//! Link libpython into every binary and test of this crate when building against ROS 2 from the
//! PyPI wheels (ROS-from-PyPI workaround 3: the wheels' librcl*.so need Python symbols).
//! `scripts/env.sh` sets UNITAC_PYTHON_LIBDIR for that setup; an apt-installed ROS needs nothing,
//! so without it this does nothing. `rustc-link-arg` does not propagate to dependents, so every
//! crate that makes binaries linking r2r needs this.
fn main() {
    println!("cargo:rerun-if-env-changed=UNITAC_PYTHON_LIBDIR");
    let dir = std::env::var("UNITAC_PYTHON_LIBDIR").unwrap_or_default();
    if !dir.is_empty() {
        println!("cargo:rustc-link-search=native={dir}");
        println!("cargo:rustc-link-arg=-Wl,--push-state,--no-as-needed,-lpython3.11,--pop-state");
    }
}
