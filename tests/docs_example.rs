//! The complete example in docs/scene-format.md is a valid scene.

#[test]
fn scene_format_example_is_valid() {
    let doc = include_str!("../docs/scene-format.md");
    let example = doc
        .find("## Complete example")
        .expect("the example section");
    let start =
        example + doc[example..].find("```toml\n").expect("example block") + "```toml\n".len();
    let end = start + doc[start..].find("```").expect("end of block");
    let scene = prism::Scene::from_toml(&doc[start..end], "docs/scene-format.md")
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.aggregate.primitives().len(), 3);
}
