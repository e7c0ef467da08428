//! Builds the project's FMUs from source and bundles each as a .fmu (a zip archive of its
//! modelDescription.xml and its binary for this platform):
//!
//! - `modbot_ff2`, `modbot_stair2` (FMI 2) and `modbot_ss3` (FMI 3): compiles each one's C
//!   source (`ff2/ff2.c`, `stair2/stair2.c`, `ss3/ss3.c`, against the FMI headers in
//!   `ff2/include` and `ss3/include`) into a shared library with the C compiler the `cc`
//!   crate finds, and bundles it with the modelDescription.xml beside it;
//! - `modbot_filter3`: builds `filter3/` (a cdylib and the program that writes its
//!   modelDescription.xml) with cargo, in a target directory of its own — cargo cannot hand
//!   a cdylib of this workspace to a build script.
//!
//! Each .fmu goes to OUT_DIR and next to the workspace's programs (`target/<profile>/`).

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

fn main() {
    if let Err(e) = build() {
        panic!("building the project's FMUs failed: {e}");
    }
}

fn build() -> Result<()> {
    let here = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR")?);
    let out = PathBuf::from(std::env::var("OUT_DIR")?);
    // OUT_DIR is <target>/<profile>/build/<package>-<hash>/out.
    let programs = out
        .ancestors()
        .nth(3)
        .ok_or("OUT_DIR is not in a target directory")?;
    let target = programs.parent().ok_or("no target directory")?;

    let mut fmus = Vec::new();
    for c in C_FMUS {
        let fmu = out.join(format!("{}.fmu", c.name));
        let library = out.join(format!("{}.so", c.name));
        compile_c(&here.join(c.source), &here.join(c.include), &library)?;
        bundle(
            &fmu,
            &fs::read(here.join(c.dir).join("modelDescription.xml"))?,
            &format!("binaries/{}/{}.so", platform(c.fmi)?, c.name),
            &fs::read(&library)?,
        )?;
        println!("cargo:rustc-env={}={}", c.env, fmu.display());
        fmus.push(fmu);
    }

    let filter3 = out.join("modbot_filter3.fmu");
    let (library, description) = cargo_build(&here.join("filter3"), &target.join("fmu-build"))?;
    bundle(
        &filter3,
        &description,
        &format!("binaries/{}/modbot_filter3.so", platform(3)?),
        &fs::read(library)?,
    )?;

    fmus.push(filter3.clone());
    for fmu in &fmus {
        let name = fmu.file_name().ok_or("no file name")?;
        fs::copy(fmu, programs.join(name))?;
    }
    println!("cargo:rustc-env=MODBOT_FILTER3_FMU={}", filter3.display());
    for watched in [
        "ff2",
        "stair2",
        "ss3",
        "filter3/src",
        "filter3/Cargo.toml",
        "filter3/Cargo.lock",
    ] {
        println!("cargo:rerun-if-changed={}", here.join(watched).display());
    }
    Ok(())
}

/// An FMU written in C: its name (the model identifier), FMI version, folder (with its
/// modelDescription.xml), source, headers, and the variable that tells the crate where it is.
struct CFmu {
    name: &'static str,
    fmi: u8,
    dir: &'static str,
    source: &'static str,
    include: &'static str,
    env: &'static str,
}

const C_FMUS: [CFmu; 3] = [
    CFmu {
        name: "modbot_ff2",
        fmi: 2,
        dir: "ff2",
        source: "ff2/ff2.c",
        include: "ff2/include",
        env: "MODBOT_FF2_FMU",
    },
    CFmu {
        name: "modbot_stair2",
        fmi: 2,
        dir: "stair2",
        source: "stair2/stair2.c",
        include: "ff2/include",
        env: "MODBOT_STAIR2_FMU",
    },
    CFmu {
        name: "modbot_ss3",
        fmi: 3,
        dir: "ss3",
        source: "ss3/ss3.c",
        include: "ss3/include",
        env: "MODBOT_SS3_FMU",
    },
];

/// The folder of an FMU's binaries for this platform: FMI 2 names it `linux64`, FMI 3
/// `x86_64-linux` (or `aarch64-linux`).
fn platform(fmi: u8) -> Result<&'static str> {
    let os = std::env::var("CARGO_CFG_TARGET_OS")?;
    let arch = std::env::var("CARGO_CFG_TARGET_ARCH")?;
    match (fmi, os.as_str(), arch.as_str()) {
        (2, "linux", "x86_64" | "aarch64") => Ok("linux64"),
        (3, "linux", "x86_64") => Ok("x86_64-linux"),
        (3, "linux", "aarch64") => Ok("aarch64-linux"),
        _ => Err(format!("no FMU platform folder for {arch}-{os}").into()),
    }
}

/// Compiles the C FMU `source`, against the headers in `include`, into the shared library
/// `library`.
fn compile_c(source: &Path, include: &Path, library: &Path) -> Result<()> {
    let compiler = cc::Build::new()
        .cargo_metadata(false)
        .opt_level(2)
        .try_get_compiler()?;
    let status = compiler
        .to_command()
        .args([
            "-shared", "-fPIC", "-std=c99", "-Wall", "-Wextra", "-Werror", "-o",
        ])
        .arg(library)
        .arg("-I")
        .arg(include)
        .arg(source)
        .arg("-lm")
        .status()?;
    if !status.success() {
        return Err(format!("the C compiler failed ({status}) on {}", source.display()).into());
    }
    Ok(())
}

/// Builds the Rust FMU crate in `dir` with cargo in `target_dir`: its library, and its
/// modelDescription.xml as its describe program writes it.
fn cargo_build(dir: &Path, target_dir: &Path) -> Result<(PathBuf, Vec<u8>)> {
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let mut command = Command::new(cargo);
    command
        .args(["build", "--locked", "--quiet", "--manifest-path"])
        .arg(dir.join("Cargo.toml"))
        .arg("--target-dir")
        .arg(target_dir);
    // What this build's cargo set for the build scripts is not for that build (clippy's
    // wrapper, this profile's flags, this target directory).
    for var in [
        "RUSTC_WORKSPACE_WRAPPER",
        "CARGO_ENCODED_RUSTFLAGS",
        "CARGO_TARGET_DIR",
    ] {
        command.env_remove(var);
    }
    let status = command.status()?;
    if !status.success() {
        return Err(format!("cargo build of {} failed ({status})", dir.display()).into());
    }
    let built = target_dir.join("debug");
    let describe = Command::new(built.join("modbot-filter3-describe")).output()?;
    if !describe.status.success() {
        let why = String::from_utf8_lossy(&describe.stderr).into_owned();
        return Err(format!("modbot-filter3-describe failed: {why}").into());
    }
    Ok((built.join("libmodbot_filter3.so"), describe.stdout))
}

/// Writes the FMU `fmu`: `description` as modelDescription.xml and `binary` at `binary_path`.
fn bundle(fmu: &Path, description: &[u8], binary_path: &str, binary: &[u8]) -> Result<()> {
    let mut zip = zip::ZipWriter::new(fs::File::create(fmu)?);
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Stored)
        .unix_permissions(0o644);
    zip.start_file("modelDescription.xml", options)?;
    zip.write_all(description)?;
    zip.start_file(binary_path, options.unix_permissions(0o755))?;
    zip.write_all(binary)?;
    zip.finish()?;
    Ok(())
}
