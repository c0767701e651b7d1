//! The scene language's reader: statements split into lines, keywords, each statement's reader, the registry and help.

/// The one statement of `s` read by `read`; the test fails on anything else (see `try_read_one`).
fn read_one<T>(
    s: &str,
    rule: lagrangian::scene::syntax::parser::Rule,
    read: for<'i> fn(
        &lagrangian::scene::syntax::parser::Reader,
        pest::iterators::Pair<'i, lagrangian::scene::syntax::parser::Rule>,
    ) -> Result<T, lagrangian::scene::SceneError>,
) -> T {
    lagrangian::scene::syntax::parser::try_read_one(s, rule, read).unwrap_or_else(|e| panic!("{e}"))
}

mod help {
    use lagrangian::scene::help::*;
    use lagrangian::scene::registry::{parse_scene, statement_words};

    #[test]
    fn every_statement_has_help_with_an_example_that_parses() {
        for word in statement_words() {
            let text = help(Some(word)).unwrap_or_else(|near| panic!("no help for `{word}` (near: {near:?})"));
            assert!(text.contains("example: "), "no help for `{word}`: {text}");
        }
        for t in TOPICS {
            let parsed = parse_scene(t.example);
            assert!(matches!(&parsed, Ok(v) if v.len() == 1), "`{}`: {parsed:?}", t.example);
        }
    }
}

/// `help` with a topic of several words (`help energy at`), in a scene as in the REPL: the
/// answer is the topic's own row, and an unknown topic is an error at its words.
mod help_topics {
    use lagrangian::scene::help::TOPICS;
    use lagrangian::scene::{ErrorKind, Mode, Options, Session};

    fn help(mode: Mode, line: &str) -> Result<String, lagrangian::scene::SceneError> {
        let mut s = Session::new(Options::new(mode));
        match mode {
            Mode::Scene => s.run_scene("help.scene", line)?,
            Mode::Repl => s.run_line(line)?,
        }
        Ok(s.take_output().join("\n"))
    }

    fn row(word: &str) -> &'static lagrangian::scene::help::Topic {
        TOPICS.iter().find(|t| t.word == word).unwrap_or_else(|| panic!("no row `{word}`"))
    }

    #[test]
    fn a_topic_of_two_words_is_its_own_row() {
        let at = row("energy at");
        let expected = format!("{}\n  {}\n  example: {}", at.form, at.about, at.example);
        for mode in [Mode::Scene, Mode::Repl] {
            assert_eq!(help(mode, "help energy at").unwrap(), expected, "{mode:?}");
            // Blanks between the words do not matter.
            assert_eq!(help(mode, "help  energy   at").unwrap(), expected, "{mode:?}");
        }
        // The point transformation, with or without its brackets.
        let point = row("transform (point)");
        for line in ["help transform (point)", "help transform point"] {
            assert!(help(Mode::Scene, line).unwrap().starts_with(point.form), "{line}");
        }
    }

    #[test]
    fn a_one_word_topic_names_the_longer_topics_it_begins() {
        let energy = row("energy");
        let text = help(Mode::Scene, "help energy").unwrap();
        assert!(text.starts_with(&format!("{}\n  {}\n  example: {}", energy.form, energy.about, energy.example)));
        assert!(text.ends_with("\n  see also: `help energy at`"), "{text}");
        let text = help(Mode::Repl, "help export").unwrap();
        assert!(text.ends_with("\n  see also: `help export poincare`"), "{text}");
        // A topic that begins no other has no such line.
        assert!(!help(Mode::Scene, "help pb").unwrap().contains("see also"));
    }

    #[test]
    fn an_unknown_topic_is_refused_at_its_words() {
        for mode in [Mode::Scene, Mode::Repl] {
            let e = help(mode, "coordinates x\nhelp enrgy at").unwrap_err();
            assert_eq!(e.kind, ErrorKind::UnknownStatement, "{e:?}");
            assert_eq!(e.message, "no help for `enrgy at`");
            // `enrgy at` is bytes 19..27 of the text.
            assert_eq!(e.span, Some((19, 27)));
            assert_eq!(e.hint.as_deref(), Some("did you mean `help energy at`?"));
            let e = help(mode, "help foo bar").unwrap_err();
            assert_eq!((e.kind, e.span), (ErrorKind::UnknownStatement, Some((5, 12))));
            assert_eq!(e.hint.as_deref(), Some("`help` lists every topic"));
        }
        // One word as before, now also an error with its place.
        let e = help(Mode::Repl, "help simulat").unwrap_err();
        assert_eq!((e.span, e.hint.as_deref()), (Some((5, 12)), Some("did you mean `help simulate`?")));
    }
}

mod registry {
    use lagrangian::scene::registry::*;
    use lagrangian::scene::ErrorKind;

    /// Every statement rule of the grammar (`stmt`'s alternatives) has exactly one row.
    #[test]
    fn every_statement_rule_has_one_row() {
        let grammar = include_str!("../../../grammar/scene.pest");
        let start = grammar.find("\nstmt = _{").expect("the `stmt` rule");
        let body = &grammar[start..];
        let body = &body[body.find('{').unwrap() + 1..body.find('}').unwrap()];
        let rules: Vec<&str> = body.split('|').map(str::trim).collect();
        assert!(rules.len() > 30, "{rules:?}");
        for name in &rules {
            let rows = REGISTRY.iter().filter(|t| t.read.is_some_and(|x| format!("{:?}", x.rule) == *name)).count();
            assert_eq!(rows, 1, "rule `{name}`");
        }
        let with_reader = REGISTRY.iter().filter(|t| t.read.is_some()).count();
        assert_eq!(with_reader, rules.len());
    }

    #[test]
    fn unknown_statement_suggests() {
        let err = parse_scene("coordinates x\nsimulat x = 1 for t in 0..1").unwrap_err();
        assert_eq!(err.kind, ErrorKind::UnknownStatement);
        assert_eq!(err.span, Some((14, 21)));
        assert!(err.hint.as_deref().is_some_and(|h| h.contains("`simulate`")), "{err:?}");
    }
}

mod parser {
    use super::read_one;
    use lagrangian::scene::ast::DefValue;
    use lagrangian::scene::statements::declare::Parameters;
    use lagrangian::scene::statements::define::Define;
    use lagrangian::scene::statements::print::Derive;
    use lagrangian::scene::syntax::parser::*;
    use lagrangian::Format;

    /// `is_kw` (its list written by `build.rs` from the grammar) names every keyword rule pest
    /// generated and nothing else: a keyword rule the script missed, or a rule it took for
    /// one, fails here (the rule names are read in a test, so the parser itself never
    /// classifies rules by their names).
    #[test]
    fn is_kw_lists_exactly_the_keyword_rules() {
        for &rule in Rule::all_rules() {
            let named_kw = format!("{rule:?}").starts_with("kw_");
            assert_eq!(is_kw(rule), named_kw, "{rule:?}");
        }
    }

    #[test]
    fn splits_lines_and_continuations() {
        let text = "coordinates x\n# a comment\nL = 1/2 m x'^2 -\n    1/2 k x^2\nH = (a +\n b)\nprint L\n  + 1\n";
        let spans = split_statements(text);
        let parts: Vec<&str> = spans.iter().map(|&(s, e)| &text[s..e]).collect();
        assert_eq!(parts, ["coordinates x", "L = 1/2 m x'^2 -\n    1/2 k x^2", "H = (a +\n b)", "print L\n  + 1"]);
    }

    #[test]
    fn simulate_keywords_end_expressions() {
        let s = read_one("simulate θ = 3.0, θ' = 0 for t in 0..20 with gauss6 dt = 0.01", Rule::simulate, |r, p| {
            r.simulate_stmt(p)
        });
        assert_eq!(s.inits.len(), 2);
        assert_eq!(s.inits[0].1.text, "3.0");
        assert_eq!(s.inits[1].0.text, "θ'");
        assert_eq!((s.t0.text.as_str(), s.t1.text.as_str()), ("0", "20"));
        assert_eq!(s.method.map(|m| m.text), Some("gauss6".to_string()));
        assert_eq!(s.dt.map(|m| m.text), Some("0.01".to_string()));
    }

    #[test]
    fn parameters_with_assumption() {
        let Parameters { params, positive } =
            read_one("parameters m = 1, l = 2/3, g = 9.81 positive", Rule::parameters, Parameters::read);
        assert!(positive);
        assert_eq!(params.len(), 3);
        assert_eq!(params[1].1.as_ref().map(|v| v.text.as_str()), Some("2/3"));
    }

    #[test]
    fn definitions_and_derivations() {
        let define = |s| read_one(s, Rule::definition, Define::read);
        assert!(matches!(define("H = legendre(L)").value, DefValue::Derivation(_)));
        assert!(matches!(define("H2 = legendre(L) + 1").value, DefValue::Expr(_)));
        let derive = |s| read_one(s, Rule::derive_stmt, Derive::read);
        assert!(matches!(derive("el as latex").format, Some(Format::Latex)));
        assert_eq!(derive("pb Lx, Ly").call.args.len(), 2);
    }
}

mod flow {
    use super::read_one;
    use lagrangian::scene::statements::canonical::{Lie, LieGenerator};
    use lagrangian::scene::statements::flow::FlowSpec;
    use lagrangian::scene::syntax::parser::Rule;

    #[test]
    fn flow_reads_a_simulate_start_and_an_output_file() {
        let f = read_one(
            "flow θ = 1, θ' = 0 for t in 0..10 tol = 1e-12 points 50 to checks.svg",
            Rule::flow_stmt,
            FlowSpec::read,
        );
        assert_eq!(f.sim.inits.len(), 2);
        assert_eq!((f.sim.t0.text.as_str(), f.sim.t1.text.as_str()), ("0", "10"));
        assert_eq!(f.sim.tol.map(|m| m.text), Some("1e-12".to_string()));
        assert_eq!(f.sim.points.map(|m| m.text), Some("50".to_string()));
        assert_eq!(f.path.map(|p| p.text), Some("checks.svg".to_string()));
        assert_eq!(f.word, (0, 4));
        // `flow` inside `lie` is still the Lie flow, not this statement.
        let lie = read_one("lie q flow order 4", Rule::lie, Lie::read);
        assert!(matches!(lie.generator, LieGenerator::Flow(None)));
    }
}
