//! Panics of the decoders Myriad does not own, turned into errors. The `laz` crate indexes its
//! arithmetic decoder's tables with values read from the chunk (a damaged COPC chunk panicked,
//! found by fuzzing) and the `dxf` crate unwraps dates beyond chrono's range: on damaged input
//! both panic where they should fail. [`catching`] runs such a call and returns the panic as an
//! error; a process-wide panic hook, installed once, keeps the message of a panic raised inside
//! those crates' sources off the terminal (on whichever thread: `laz` decodes on rayon's), and
//! passes every other panic to the hook that was there before.

use std::sync::Once;

/// Source paths of the crates whose panics [`catching`] turns into errors (as Cargo unpacks
/// them: `.../laz-0.13.0/src/decoders.rs`).
const GUARDED: [&str; 2] = ["/laz-", "/dxf-"];

fn guarded(file: &str) -> bool {
    GUARDED.iter().any(|g| file.contains(g))
}

/// Runs `f`; a panic becomes `Err` with its message. Only call code whose panics mean damaged
/// input (a decoder of another crate), never code of ours: a panic of ours is a bug to see.
pub fn catching<T>(f: impl FnOnce() -> T) -> Result<T, String> {
    static HOOK: Once = Once::new();
    HOOK.call_once(|| {
        let before = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !info.location().is_some_and(|l| guarded(l.file())) {
                before(info);
            }
        }));
    });
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).map_err(|p| {
        p.downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| p.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "a value out of range".into())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_becomes_its_message() {
        assert_eq!(catching(|| 7), Ok(7));
        let e = catching(|| -> u8 { panic!("index 9 out of range") }).unwrap_err();
        assert_eq!(e, "index 9 out of range");
        assert!(guarded(
            "/root/.cargo/registry/src/x/laz-0.13.0/src/decoders.rs"
        ));
        assert!(!guarded("crates/myriad-io/src/las.rs"));
    }
}
