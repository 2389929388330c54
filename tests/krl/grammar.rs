//! `grammars/krl.ebnf` and the parser stay in step: every production named in the grammar is
//! a parser function (a `fn` in src/krl/syntax/ returning `PResult`) and every parser function is a
//! production.

use super::root;
use std::collections::BTreeSet;

/// Production names: `name =` at the start of a line, outside `(* … *)` comments.
fn productions(ebnf: &str) -> BTreeSet<String> {
    let mut text = String::new();
    let mut rest = ebnf;
    while let Some(a) = rest.find("(*") {
        text.push_str(&rest[..a]);
        let b = rest[a..].find("*)").expect("closed comment") + a + 2;
        rest = &rest[b..];
    }
    text.push_str(rest);
    text.lines()
        .filter_map(|l| {
            let name: String = l
                .chars()
                .take_while(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || *c == '_')
                .collect();
            (!name.is_empty() && l[name.len()..].trim_start().starts_with('=')).then_some(name)
        })
        .collect()
}

/// Functions whose return type is `PResult<…>`.
fn parser_functions(rust: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut rest = rust;
    while let Some(p) = rest.find("fn ") {
        let after = &rest[p + 3..];
        rest = after;
        let name: String = after
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        let Some(body) = after.find('{') else { break };
        let sig = &after[..body];
        // The `->` after the parameter list (matched parentheses: closures in parameters).
        let Some(open) = sig.find('(') else { continue };
        let mut depth = 0;
        let mut params_end = None;
        for (k, c) in sig[open..].char_indices() {
            match c {
                '(' => depth += 1,
                ')' => {
                    depth -= 1;
                    if depth == 0 {
                        params_end = Some(open + k);
                        break;
                    }
                }
                _ => {}
            }
        }
        let Some(params_end) = params_end else {
            continue;
        };
        if let Some(arrow) = sig[params_end..].find("->") {
            if sig[params_end + arrow + 2..]
                .trim_start()
                .starts_with("PResult")
            {
                out.insert(name);
            }
        }
    }
    out
}

#[test]
fn grammar_names_exactly_the_parser_functions() {
    let ebnf = std::fs::read_to_string(root().join("grammars/krl.ebnf")).unwrap();
    let grammar = productions(&ebnf);
    let mut code = BTreeSet::new();
    let mut dirs = vec![root().join("src/krl/syntax")];
    while let Some(dir) = dirs.pop() {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                dirs.push(p);
            } else if p.extension().is_some_and(|x| x == "rs") {
                code.extend(parser_functions(&std::fs::read_to_string(&p).unwrap()));
            }
        }
    }
    assert!(grammar.len() > 40, "{grammar:?}");
    let missing_fn: Vec<_> = grammar.difference(&code).collect();
    let missing_rule: Vec<_> = code.difference(&grammar).collect();
    assert!(
        missing_fn.is_empty() && missing_rule.is_empty(),
        "productions without a parser function: {missing_fn:?}; parser functions without a production: {missing_rule:?}"
    );
}

#[test]
fn the_scanners_themselves_work() {
    assert_eq!(
        productions("(* a = b ; *)\nfoo = bar ;\n  baz = x ;\nqux_2= y;"),
        ["foo", "qux_2"].iter().map(|s| s.to_string()).collect()
    );
    let rust = "fn a<'x>(i: &'x [u8]) -> PResult<'x, u8> {}\nfn b() -> impl Fn(&[u8]) -> PResult<'_, u8> {}\nfn c() -> Fails<'_, u8> {}\nfn d<'a>(p: impl FnMut(&'a [u8]) -> PResult<'a, u8>) -> impl FnMut(&'a [u8]) -> PResult<'a, u8> {}";
    assert_eq!(
        parser_functions(rust),
        ["a"].iter().map(|s| s.to_string()).collect()
    );
}
