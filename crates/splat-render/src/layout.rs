//! Uniform and storage layouts written twice, once as a `#[repr(C)]` Rust
//! struct uploaded with `bytemuck` and once as a WGSL struct, checked
//! against each other: [`check`] parses the WGSL with naga (wgpu's own
//! shader front end, so the offsets are the ones the device uses) and
//! compares the struct's size and each member's offset with the Rust
//! struct's. The [`wgsl_layout!`](crate::wgsl_layout) macro gathers the
//! Rust side. A member added, removed, reordered or retyped on one side
//! only fails the crate's layout tests instead of corrupting a uniform.

/// Checks the WGSL struct `name` in `source` against a Rust struct of
/// `size` bytes whose fields are `fields` (name, byte offset): the same
/// size, and every WGSL member at the offset of the Rust field of the same
/// name. Fields on either side without a counterpart must be padding
/// (named `pad…`).
///
/// # Errors
/// A message naming the struct and each difference; or the parse error.
pub fn check(
    source: &str,
    name: &str,
    size: usize,
    fields: &[(&str, usize)],
) -> Result<(), String> {
    let module = naga::front::wgsl::parse_str(source)
        .map_err(|e| format!("the WGSL does not parse: {}", e.emit_to_string(source)))?;
    let (members, span) = module
        .types
        .iter()
        .find_map(|(_, ty)| match (&ty.name, &ty.inner) {
            (Some(n), naga::TypeInner::Struct { members, span }) if n == name => {
                Some((members, *span))
            }
            _ => None,
        })
        .ok_or_else(|| format!("no struct `{name}` in the WGSL"))?;
    let mut problems = Vec::new();
    if span as usize != size {
        problems.push(format!("{span} bytes in WGSL, {size} in Rust"));
    }
    for m in members {
        let member = m.name.as_deref().unwrap_or("?");
        match fields.iter().find(|(f, _)| *f == member) {
            // Padding is checked by the size and the other offsets.
            None if member.starts_with("pad") => {}
            Some(&(_, offset)) if offset == m.offset as usize => {}
            Some(&(_, offset)) => problems.push(format!(
                "`{member}` at byte {} in WGSL, {offset} in Rust",
                m.offset
            )),
            None => problems.push(format!("`{member}` is not in the Rust struct")),
        }
    }
    for (field, _) in fields {
        if !field.starts_with("pad") && !members.iter().any(|m| m.name.as_deref() == Some(field)) {
            problems.push(format!("`{field}` is not in the WGSL struct"));
        }
    }
    if problems.is_empty() {
        Ok(())
    } else {
        Err(format!("struct `{name}`: {}", problems.join("; ")))
    }
}

/// Checks a Rust struct against the WGSL struct of the same layout:
/// `wgsl_layout!(source, "WgslName", RustType { field, field, … })` lists
/// every field of the Rust struct, and returns [`check`]'s result.
#[macro_export]
macro_rules! wgsl_layout {
    ($source:expr, $name:expr, $ty:ty { $($field:ident),* $(,)? }) => {
        $crate::layout::check(
            $source,
            $name,
            ::std::mem::size_of::<$ty>(),
            &[$((stringify!($field), ::std::mem::offset_of!($ty, $field))),*],
        )
    };
}

#[cfg(test)]
mod tests {
    #[repr(C)]
    struct Good {
        a: f32,
        pad0: [u32; 3],
        b: [f32; 4],
        c: u32,
        pad1: [u32; 3],
    }

    #[repr(C)]
    struct Swapped {
        c: u32,
        pad0: [u32; 3],
        b: [f32; 4],
        a: f32,
        pad1: [u32; 3],
    }

    const WGSL: &str = "struct S { a: f32, b: vec4<f32>, c: u32 };\n\
                        @group(0) @binding(0) var<uniform> s: S;";

    #[test]
    fn a_matching_struct_passes_and_a_different_one_is_named() {
        crate::wgsl_layout!(
            WGSL,
            "S",
            Good {
                a,
                pad0,
                b,
                c,
                pad1
            }
        )
        .unwrap();
        let e = crate::wgsl_layout!(
            WGSL,
            "S",
            Swapped {
                c,
                pad0,
                b,
                a,
                pad1
            }
        )
        .unwrap_err();
        assert!(e.contains("`a` at byte 0 in WGSL, 32 in Rust"), "{e}");
        assert!(e.contains("`c` at byte 32 in WGSL, 0 in Rust"), "{e}");
        let e = crate::wgsl_layout!(
            WGSL,
            "T",
            Good {
                a,
                pad0,
                b,
                c,
                pad1
            }
        )
        .unwrap_err();
        assert!(e.contains("no struct `T`"), "{e}");
    }
}
