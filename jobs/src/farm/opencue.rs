//! OpenCue job spec (XML, `cjsl-1.15.dtd`, vendored with its license in `jobs/farm/opencue/`).
//!
//! One layer per stage; a layer's frames are its task indices (OpenCue substitutes `#IFRAME#` in the command),
//! chunk 1, and `LAYER_ON_LAYER` dependencies mirror the stage dependencies of the graph. Submit it with
//! `cueadmin`/`pycue` (`opencue.api.launchSpecAndWait`) or CueSubmit's "load spec"; see docs/farms.md.

use super::command::{shell_quote, FarmCommand};
use super::graph::FarmGraph;

/// Show, shot and user: OpenCue files every job under them.
#[derive(Debug, Clone, PartialEq)]
pub struct CueIdentity {
    pub show: String,
    pub shot: String,
    pub user: String,
}

pub fn opencue_spec(name: &str, graph: &FarmGraph, cmd: &FarmCommand, who: &CueIdentity) -> String {
    let job = nmtoken(&format!("crease_{name}"));
    let mut x = String::new();
    x.push_str("<?xml version=\"1.0\"?>\n");
    x.push_str(
        "<!DOCTYPE spec PUBLIC \"SPI Cue  Specification Language\" \
         \"http://localhost:8080/spcue/dtd/cjsl-1.15.dtd\">\n",
    );
    x.push_str("<spec>\n");
    x.push_str(&format!("  <show>{}</show>\n", esc(&who.show)));
    x.push_str(&format!("  <shot>{}</shot>\n", esc(&who.shot)));
    x.push_str(&format!("  <user>{}</user>\n", esc(&who.user)));
    x.push_str(&format!("  <job name=\"{job}\">\n"));
    x.push_str("    <paused>False</paused>\n");
    x.push_str("    <maxretries>3</maxretries>\n");
    x.push_str("    <layers>\n");
    for s in &graph.stages {
        let args = cmd.stage_args(graph, s.stage, "#IFRAME#");
        let line: Vec<String> = std::iter::once(cmd.exe.as_str())
            .chain(args.iter().map(String::as_str))
            .map(shell_quote)
            .collect();
        x.push_str(&format!(
            "      <layer name=\"{}\" type=\"Render\">\n",
            s.stage.title()
        ));
        x.push_str(&format!("        <cmd>{}</cmd>\n", esc(&line.join(" "))));
        x.push_str(&format!("        <range>0-{}</range>\n", s.tasks.len() - 1));
        x.push_str("        <chunk>1</chunk>\n");
        x.push_str("        <services>\n          <service>shell</service>\n        </services>\n");
        x.push_str("      </layer>\n");
    }
    x.push_str("    </layers>\n");
    x.push_str("  </job>\n");
    x.push_str("  <depends>\n");
    for s in &graph.stages {
        for d in &s.depends_on {
            x.push_str("    <depend type=\"LAYER_ON_LAYER\">\n");
            x.push_str(&format!("      <depjob>{job}</depjob>\n"));
            x.push_str(&format!("      <deplayer>{}</deplayer>\n", s.stage.title()));
            x.push_str(&format!("      <onjob>{job}</onjob>\n"));
            x.push_str(&format!("      <onlayer>{}</onlayer>\n", d.title()));
            x.push_str("    </depend>\n");
        }
    }
    x.push_str("  </depends>\n");
    x.push_str("</spec>\n");
    x
}

/// XML text escaping.
fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// An XML NMTOKEN (letters, digits, `.-_:`), as OpenCue's DTD requires of job names.
fn nmtoken(s: &str) -> String {
    let t: String = s
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || ".-_".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect();
    if t.is_empty() {
        "crease".into()
    } else {
        t
    }
}
