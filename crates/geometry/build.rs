//! Compiles the vendored xatlas (crates/geometry/xatlas, MIT, jpcy/xatlas at f700c77) with its C
//! API, single-threaded (`XA_MULTITHREADED=0`) so the same mesh always unwraps to the same bytes.

fn main() {
    println!("cargo:rerun-if-changed=xatlas/xatlas.cpp");
    println!("cargo:rerun-if-changed=xatlas/xatlas.h");
    println!("cargo:rerun-if-changed=xatlas/xatlas_c.h");
    cc::Build::new()
        .cpp(true)
        .file("xatlas/xatlas.cpp")
        .define("XATLAS_C_API", "1")
        .define("XA_MULTITHREADED", "0")
        .define("NDEBUG", None)
        // xatlas prints warnings (and failed internal asserts) to stdout; igi's stdout is its
        // report, so they are compiled out
        .define("XA_PRINT(...)", "")
        .define("XA_PRINT_WARNING(...)", "")
        .flag_if_supported("-std=c++14")
        .flag_if_supported("-fno-fast-math")
        .flag_if_supported("-ffp-contract=off")
        .warnings(false)
        .opt_level(2)
        .compile("xatlas");
}
