//! The demo report's HTML builder and its structural check, without a browser (the browser
//! check of a real demo run is `cargo xtask report-check`). The end-to-end quick demo is
//! `#[ignore]`d here (≈ 15–35 s, test profile = opt-level 3): `cargo test -p pbm-demo --test
//! demo_report -- --ignored`.

use pbm_demo::demo::{stamp_text, DemoOptions, REQUIRED_SECTIONS};
use pbm_report::report_html::{check, render, svg_element, Block, Cell, Page, Section, Table};
use plotters::prelude::*;

/// A real plotters SVG with one line, as the report inlines them.
fn line_svg() -> String {
    let mut buf = String::new();
    {
        let root = SVGBackend::with_string(&mut buf, (320, 200)).into_drawing_area();
        root.fill(&WHITE).unwrap();
        let mut chart = ChartBuilder::on(&root).margin(5).build_cartesian_2d(0.0..1.0, 0.0..1.0).unwrap();
        chart.draw_series(LineSeries::new([(0.0, 0.0), (0.5, 0.8), (1.0, 1.0)], &BLUE)).unwrap();
        root.present().unwrap();
    }
    buf
}

/// An SVG that draws nothing but its background.
fn blank_svg() -> String {
    let mut buf = String::new();
    {
        let root = SVGBackend::with_string(&mut buf, (320, 200)).into_drawing_area();
        root.fill(&WHITE).unwrap();
        root.present().unwrap();
    }
    buf
}

fn table() -> Table {
    let mut t = Table::new("accuracy <by> classifier", &["classifier", "accuracy"]);
    t.row(vec![Cell::strong("ours_int8"), Cell::text("99.6 %").with_background((200, 255, 200))]);
    t.row(vec![Cell::text("paper_raw"), Cell::mono("72.0 %")]);
    t
}

fn full_page() -> Page {
    let sections = REQUIRED_SECTIONS
        .iter()
        .map(|id| {
            let mut s = Section::new(id, format!("Section {id}"));
            s.push(Block::Para(format!("text of {id} & <friends>")));
            s.push(Block::Table(table()));
            s.push(Block::Figure { svg: line_svg(), caption: "a line".into() });
            s
        })
        .collect();
    Page { title: "demo <report>".into(), subtitle: "seed 1".into(), sections }
}

#[test]
fn a_complete_page_passes_the_check_with_its_counts() {
    let page = full_page();
    let html = render(&page);
    let found = check(&html, &REQUIRED_SECTIONS).unwrap();
    assert_eq!(found.sections, REQUIRED_SECTIONS);
    assert_eq!(found.svgs, REQUIRED_SECTIONS.len());
    assert_eq!(found.tables, REQUIRED_SECTIONS.len());
    assert_eq!(found.table_rows, 2 * REQUIRED_SECTIONS.len());
    // Self-contained: inline style, no script, no link, no external URL but the SVG namespace.
    assert!(html.contains("<style>"));
    let without_ns = html.replace("http://www.w3.org/2000/svg", "");
    assert!(!without_ns.contains("http"), "external reference");
    assert!(!html.contains("<script") && !html.contains("<link"));
    // Text is escaped; the table cells carry their styles.
    assert!(html.contains("<title>demo &lt;report&gt;</title>"));
    assert!(html.contains("text of run &amp; &lt;friends&gt;"));
    assert!(html.contains("<caption>accuracy &lt;by&gt; classifier</caption>"));
    assert!(html.contains("style=\"background:#c8ffc8\""));
    assert!(html.contains("<td class=\"mono\">72.0 %</td>"));
    assert!(html.contains("<td class=\"num\" style=\"background:#c8ffc8\">99.6 %</td>"));
    // Every section is reachable from the navigation.
    for id in REQUIRED_SECTIONS {
        assert!(html.contains(&format!("<a href=\"#{id}\">")), "{id}");
    }
}

#[test]
fn the_check_finds_what_a_reader_would_miss() {
    // A required section missing.
    let mut page = full_page();
    page.sections.retain(|s| s.id != "audit");
    assert_eq!(check(&render(&page), &REQUIRED_SECTIONS).unwrap_err(), "section `audit` missing");

    // An empty section.
    let mut page = full_page();
    page.sections.iter_mut().find(|s| s.id == "classifiers").unwrap().blocks.clear();
    let e = check(&render(&page), &REQUIRED_SECTIONS).unwrap_err();
    assert!(e.contains("classifiers") && e.contains("empty"), "{e}");

    // A plot that draws nothing.
    let mut page = full_page();
    page.sections[5].blocks.push(Block::Figure { svg: blank_svg(), caption: "empty".into() });
    let e = check(&render(&page), &REQUIRED_SECTIONS).unwrap_err();
    assert!(e.contains("draws nothing"), "{e}");

    // A table without rows, and one whose cells are all empty.
    for rows in [vec![], vec![vec![Cell::text(""), Cell::text("")]]] {
        let mut page = full_page();
        page.sections[7].blocks.push(Block::Table(Table { caption: "t".into(), header: vec!["a".into()], rows }));
        let e = check(&render(&page), &REQUIRED_SECTIONS).unwrap_err();
        assert!(e.contains("no filled body rows"), "{e}");
    }

    // A figure whose markup is not SVG shows a visible note instead of raw text.
    let mut page = full_page();
    page.sections[0].blocks = vec![Block::Figure { svg: "<b>not svg</b>".into(), caption: String::new() }];
    let html = render(&page);
    assert!(html.contains("(plot missing)") && !html.contains("<b>not svg</b>"));

    // Scripts and external resources are refused.
    let html = render(&full_page()).replace("</main>", "<script>alert(1)</script></main>");
    assert!(check(&html, &REQUIRED_SECTIONS).unwrap_err().contains("script"));
    let html = render(&full_page()).replace("</main>", "<img src=\"http://example.com/x.png\"></main>");
    assert!(check(&html, &REQUIRED_SECTIONS).is_err());

    // Not a document at all.
    assert!(check("<p>hello</p>", &[]).is_err());
}

#[test]
fn svg_documents_are_inlined_as_their_svg_element() {
    let doc = format!("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n{}\n", line_svg());
    let el = svg_element(&doc).unwrap();
    assert!(el.starts_with("<svg") && el.ends_with("</svg>"));
    assert!(el.contains("viewBox"), "scales with the page");
    let mut page = full_page();
    page.sections[0].blocks = vec![Block::Gallery(vec![(doc.clone(), "a".into()), (doc, "b".into())])];
    let html = render(&page);
    assert!(!html.contains("<?xml"));
    assert_eq!(check(&html, &REQUIRED_SECTIONS).unwrap().svgs, REQUIRED_SECTIONS.len() + 1);
}

#[test]
fn page_check_refuses_code_references_in_the_text() {
    use pbm_report::report_html::code_reference;
    assert_eq!(
        code_reference("<p>replayed through pbm::pipeline::Pipeline</p>"),
        Some("pbm::pipeline::Pipeline".into())
    );
    assert_eq!(code_reference("<p>see src/twin.rs.</p>"), Some("src/twin.rs".into()));
    assert_eq!(code_reference("<p>aim (issue 6)</p>").as_deref(), Some("issue 6"));
    assert_eq!(code_reference("<p>(SPEC §6)</p>").as_deref(), Some("§6"));
    // Markup, styles and plots are not text; times and ratios are not paths.
    let ok = "<style>a::before{}</style><svg><text>x::y</text></svg><p>at 12:30:58, 3:1, an issue of trust</p>";
    assert_eq!(code_reference(ok), None);
}

#[test]
fn demo_defaults_and_the_data_stamp() {
    let a = DemoOptions::default();
    assert_eq!(a.seed, pbm_demo::demo::DEFAULT_SEED);
    assert_eq!(a.data_dir(), std::path::PathBuf::from("data/demo-fleet"));
    let g = a.generate_options();
    // The paper's protocol (SPEC §6): 5 × 1100 + 5 × 50 traces, six locomotives.
    assert_eq!((g.per_class, g.test_per_class, g.locomotives, g.classes.len()), (1100, 50, 6, 5));
    assert_eq!(g.seed, a.seed);
    let quick = DemoOptions { quick: true, out: "target/x".into(), ..a.clone() };
    assert_eq!(quick.data_dir(), std::path::PathBuf::from("target/x/fleet"));
    assert!(quick.generate_options().per_class < 100);
    // The stamp changes with anything that changes the data.
    let s = stamp_text(&g);
    assert!(s.contains(&format!("seed {}", a.seed)) && s.contains(env!("CARGO_PKG_VERSION")));
    let other_seed = DemoOptions { seed: a.seed + 1, ..a.clone() }.generate_options();
    assert_ne!(stamp_text(&other_seed), s);
    assert_ne!(stamp_text(&quick.generate_options()), s);
}

/// The whole quick demo into a temporary directory: the page passes its check, names the seed,
/// and a second run reuses the data set.
#[test]
#[ignore = "runs the quick demo (≈ 15–35 s); cargo test -p pbm-demo --test demo_report -- --ignored"]
fn quick_demo_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    // The record of the real-data audit, from the repository root (tests run in the crate).
    let metro = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(pbm_lab::metro::DEFAULT_PATH);
    let a = DemoOptions { quick: true, out: dir.path().join("report"), metro, ..DemoOptions::default() };
    pbm_demo::demo::run(&a).unwrap();
    let html = std::fs::read_to_string(a.out.join("index.html")).unwrap();
    let found = check(&html, &REQUIRED_SECTIONS).unwrap();
    assert!(found.svgs >= 20 && found.tables >= 15, "{found:?}");
    assert_eq!(found.sections[0], "fleet", "the report leads with the fleet");
    // The fleet table links a page per locomotive, written next to the index and checked.
    let pages: Vec<String> = std::fs::read_dir(&a.out)
        .unwrap()
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| n.starts_with("loco-") && n.ends_with(".html"))
        .collect();
    assert_eq!(pages.len(), a.fleet_options().wear.len(), "{pages:?}");
    for p in &pages {
        assert!(html.contains(&format!("<a href=\"{p}\">")), "{p} linked");
        let page = std::fs::read_to_string(a.out.join(p)).unwrap();
        check(&page, &pbm_fleet::report::LOCOMOTIVE_SECTIONS).unwrap();
    }
    // The failing transducer is a sensor warning, the worn brakes early warnings.
    assert!(html.contains("the transducer, not the brake"));
    assert!(html.contains("leak drifting toward") && html.contains("orifice drifting toward"));
    // The real-data audit beside the synthetic one.
    assert!(html.contains("Real record: MetroPT-3 air production unit"));
    assert!(html.contains(&format!("seed {}", a.seed)));
    let stamp = std::fs::read_to_string(a.data_dir().join(pbm_demo::demo::STAMP)).unwrap();
    assert_eq!(stamp, stamp_text(&a.generate_options()));
    pbm_demo::demo::run(&a).unwrap();
    let html = std::fs::read_to_string(a.out.join("index.html")).unwrap();
    assert!(html.contains("reused: its stamp matched"));
}
