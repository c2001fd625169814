//! Bounds on YAML from outside (scene files, a bag's metadata.yaml), checked before parsing.
//!
//! libyaml (under serde_yaml) keeps one "possible simple key" per open flow collection and walks
//! all of them for every token, so `[[[[...]]]]` nested n deep costs O(n^2) before serde_yaml's
//! recursion limit is reached: 100 000 levels (200 KB) took 30 s. [`check`] is one linear pass
//! that measures the flow nesting depth (brackets outside quoted strings, comments and block
//! scalars) and refuses text over a size or depth limit, so any input is answered in
//! milliseconds. Block nesting (indentation) costs libyaml nothing extra and is stopped by
//! serde_yaml's own recursion limit.

use thiserror::Error;

/// Deepest flow nesting (`[` / `{`) accepted; real files use 2 or 3.
pub const MAX_FLOW_DEPTH: usize = 64;
/// Most nodes (lines, collection starts, entries) accepted: serde_yaml keeps every parser event
/// in memory (about 250 bytes each) before deserializing, so 4 MiB of `[[1]], [[1]], ...` cost
/// 1 GB and 1.1 s. A metadata.yaml of 1 000 topics has about 30 000.
pub const MAX_NODES: usize = 200_000;

/// Why YAML text was refused before parsing.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum YamlBoundError {
    #[error("{len} bytes, more than {max}")]
    TooLarge { len: usize, max: usize },
    #[error(
        "flow collections ([...] / {{...}}) nested more than {MAX_FLOW_DEPTH} deep at line {line}"
    )]
    TooDeep { line: usize },
    #[error("more than {MAX_NODES} YAML nodes (at line {line})")]
    TooManyNodes { line: usize },
}

/// Refuse `text` if it is longer than `max_bytes` or nests flow collections deeper than
/// [`MAX_FLOW_DEPTH`]. Linear in the text; never rejects a file that serde_yaml would parse
/// within those bounds (it may accept text that fails to parse: the parser says why).
pub fn check(text: &str, max_bytes: usize) -> Result<(), YamlBoundError> {
    if text.len() > max_bytes {
        return Err(YamlBoundError::TooLarge {
            len: text.len(),
            max: max_bytes,
        });
    }
    let mut depth = 0usize;
    // Open quoted scalar: its quote character (quoted scalars may span lines).
    let mut quote: Option<u8> = None;
    // Inside a block scalar (`|` / `>`): lines indented more than this belong to it.
    let mut block_scalar: Option<usize> = None;
    let mut nodes = 0usize;
    for (n, line) in text.lines().enumerate() {
        nodes += 1;
        let b = line.as_bytes();
        let indent = b.iter().take_while(|&&c| c == b' ').count();
        if let Some(parent) = block_scalar {
            if indent > parent || b[indent..].is_empty() {
                continue;
            }
            block_scalar = None;
        }
        let mut prev = b' ';
        let mut i = indent;
        while i < b.len() {
            let c = b[i];
            if let Some(q) = quote {
                if c == b'\\' && q == b'"' {
                    i += 1;
                } else if c == q {
                    if q == b'\'' && b.get(i + 1) == Some(&b'\'') {
                        i += 1;
                    } else {
                        quote = None;
                    }
                }
                prev = c;
                i += 1;
                continue;
            }
            let at_node_start = matches!(prev, b' ' | b'\t' | b'[' | b'{' | b',' | b':' | b'-');
            let indicator = (matches!(c, b'-' | b'?' | b':')
                && matches!(b.get(i + 1), None | Some(b' ' | b'\t')))
                || (c == b',' && depth > 0);
            if indicator || (matches!(c, b'[' | b'{') && (depth > 0 || at_node_start)) {
                nodes += 1;
                if nodes > MAX_NODES {
                    return Err(YamlBoundError::TooManyNodes { line: n + 1 });
                }
            }
            match c {
                b'#' if matches!(prev, b' ' | b'\t') => break,
                b'\'' | b'"' if at_node_start => quote = Some(c),
                b'[' | b'{' if depth > 0 || at_node_start => {
                    depth += 1;
                    if depth > MAX_FLOW_DEPTH {
                        return Err(YamlBoundError::TooDeep { line: n + 1 });
                    }
                }
                // Inside a plain scalar in block context (`a: x[`): text, not a collection.
                b'[' | b'{' => {
                    prev = b'x';
                    i += 1;
                    continue;
                }
                b']' | b'}' if depth > 0 => depth -= 1,
                b'|' | b'>' if depth == 0 && at_node_start => {
                    // A block scalar header: the rest of the line is indicators or a comment.
                    block_scalar = Some(indent);
                    break;
                }
                _ => {}
            }
            prev = c;
            i += 1;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deep_flow_nesting_is_refused_with_its_line() {
        let deep = format!("a: 1\nb: {}{}\n", "[".repeat(65), "]".repeat(65));
        assert_eq!(
            check(&deep, 1 << 20),
            Err(YamlBoundError::TooDeep { line: 2 })
        );
        let ok = format!("b: {}{}\n", "[".repeat(64), "]".repeat(64));
        assert_eq!(check(&ok, 1 << 20), Ok(()));
        assert!(matches!(
            check("abc", 2),
            Err(YamlBoundError::TooLarge { len: 3, max: 2 })
        ));
    }

    #[test]
    fn node_count_is_bounded() {
        let wide = format!("a: [{}]\n", vec!["[[1]]"; MAX_NODES / 2].join(", "));
        assert!(matches!(
            check(&wide, 4 << 20),
            Err(YamlBoundError::TooManyNodes { line: 1 })
        ));
        let dashes = "- ".repeat(MAX_NODES + 1);
        assert!(matches!(
            check(&dashes, 4 << 20),
            Err(YamlBoundError::TooManyNodes { line: 1 })
        ));
        let ok = format!("a: [{}]\n", vec!["[[1]]"; MAX_NODES / 4].join(", "));
        assert_eq!(check(&ok, 4 << 20), Ok(()));
    }

    #[test]
    fn brackets_in_strings_comments_and_block_scalars_do_not_count() {
        let many = "[".repeat(100);
        for text in [
            format!("a: '{many}'\n"),
            format!("a: \"{many}\"\n"),
            format!("a: 1 # {many}\n"),
            format!("a: x{many}\n"),
            format!("a: |\n  {many}\n  {many}\nb: [1, 2]\n"),
            format!("a: ['it''s {many}', \"\\\" {many}\"]\n"),
        ] {
            assert_eq!(check(&text, 1 << 20), Ok(()), "{text}");
            serde_yaml::from_str::<serde_yaml::Value>(&text).unwrap();
        }
    }
}
