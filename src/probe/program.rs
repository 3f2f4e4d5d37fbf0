//! The probing program: the same scan as [`super::scan`], written for the
//! controller to run on its own, since each step depends on the contacts
//! before it.
//!
//! The algorithm is written once as a small structured program (variables,
//! guarded moves, if/while) and printed in either dialect:
//!
//! - ISO (LinuxCNC RS274NGC): a guarded move is `G38.3` (probe towards, no
//!   error when nothing is touched); `#5070` says whether it touched and
//!   `#5061`/`#5062` where. The first two approaches are `G38.2`, which
//!   stops the program with an error when the part is not there. Contacts
//!   go to a log file (`LOGOPEN`/`LOG`).
//! - Turbo PMAC: a guarded move is a RAPID move-until-trigger,
//!   `X(..)^0 Y(..)^0`: the acoustic emission detector's threshold output
//!   is wired to the capture flag of both motors, the motors stop, and the
//!   zero post-trigger distance brings them back to the captured position.
//!   The program reads the position back from the motors' actual-position
//!   registers (the Turbo manual's suggested `M162`/`M262`), calls it a
//!   touch when the move stopped short of its end, and keeps the contacts
//!   in P-variables (`P2000` on, two per contact) for the host to read.

use super::scan::ScanParams;
use super::tip::Probe;

/// Which controller the program is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dialect {
    /// LinuxCNC-style RS274NGC with O-word control flow and G38.x.
    Iso,
    /// Turbo PMAC motion program with move-until-trigger.
    Pmac,
}

/// Controller settings the program needs besides the scan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControllerSettings {
    /// Encoder counts per mm of the X and Y motors (PMAC only).
    pub counts_per_mm: f64,
    /// PMAC motion program number.
    pub prog: u32,
}

impl Default for ControllerSettings {
    fn default() -> Self {
        ControllerSettings {
            counts_per_mm: 5000.0,
            prog: 50,
        }
    }
}

enum St {
    Note(String),
    Set(&'static str, String),
    /// Guarded move to (x, y); `must` = the approach must touch (stop
    /// otherwise). Sets `hit`, `cx`, `cy`, `hdx`, `hdy`.
    Guarded(String, String, bool),
    /// Unguarded move to (x, y) (backing off along a free path).
    Move(String, String),
    If(String, Vec<St>, Vec<St>),
    Block(Vec<St>),
    While(String, Vec<St>),
    Record,
    Stop(u32, &'static str),
}

const VARS: [&str; 43] = [
    "rs", "ro", "dx", "dy", "maxn", "appr", "sx", "sy", "k", "side", "trav", "hit", "cx", "cy", "hdx", "hdy", "px",
    "py", "pdx", "pdy", "qx", "qy", "qdx", "qdy", "fx", "fy", "fdx", "fdy", "wx", "wy", "wl", "ux", "uy", "nx", "ny",
    "ex", "ey", "mx", "my", "ml", "tl", "bk", "qtl",
];

fn set(v: &'static str, e: impl Into<String>) -> St {
    St::Set(v, e.into())
}

/// Back off from the contact at (x, y), touched moving along (dx, dy)
/// after running `run`: by R_o, or by `run` if less, so the way back is
/// the free way it came.
fn back_off(x: &str, y: &str, dx: &str, dy: &str, run: &str) -> Vec<St> {
    vec![
        set("bk", "{ro}"),
        St::If(format!("{run} LT {{ro}}"), vec![set("bk", run.to_string())], vec![]),
        St::Move(format!("{x}-{dx}*{{bk}}"), format!("{y}-{dy}*{{bk}}")),
    ]
}

/// The algorithm, once for both dialects. Expressions use `{name}` for
/// variables, `(` `)`, `SQRT`, `ABS` and the comparisons `GT LT GE EQ AND`.
fn algorithm(p: &ScanParams, max_points: usize) -> Vec<St> {
    let d = p.dir / p.dir.norm();
    let n = |x: f64| {
        let mut s = String::new();
        crate::formats::push_num(&mut s, x);
        s
    };
    let after_touch = |then: Vec<St>| St::If("{hit} EQ 0".into(), then, vec![]);
    vec![
        St::Note("scan parameters".into()),
        set("rs", n(p.step_mm)),
        set("ro", n(p.offset_mm)),
        set("dx", n(d.x)),
        set("dy", n(d.y)),
        set("maxn", max_points.to_string()),
        set("appr", n(p.max_approach_mm)),
        set("sx", n(p.start.x)),
        set("sy", n(p.start.y)),
        St::Note("first contact along the initial direction".into()),
        St::Guarded("{sx}+{dx}*{appr}".into(), "{sy}+{dy}*{appr}".into(), true),
        set("k", "0"),
        St::Record,
        set("fx", "{cx}"),
        set("fy", "{cy}"),
        set("fdx", "{hdx}"),
        set("fdy", "{hdy}"),
        St::Note("second start: R_s to the left of the first".into()),
        St::Block(back_off("{cx}", "{cy}", "{hdx}", "{hdy}", "{tl}")),
        St::Guarded("{sx}-{dy}*{rs}".into(), "{sy}+{dx}*{rs}".into(), false),
        St::If("{hit} EQ 1".into(), vec![St::Stop(4, "second start blocked")], vec![]),
        St::Guarded("{sx}-{dy}*{rs}+{dx}*{appr}".into(), "{sy}+{dx}*{rs}+{dy}*{appr}".into(), true),
        St::Record,
        set("px", "{fx}"),
        set("py", "{fy}"),
        set("qx", "{cx}"),
        set("qy", "{cy}"),
        set("qdx", "{hdx}"),
        set("qdy", "{hdy}"),
        set("qtl", "{tl}"),
        set("wx", "{qx}-{px}"),
        set("wy", "{qy}-{py}"),
        set("trav", "SQRT({wx}*{wx}+{wy}*{wy})"),
        St::Note("material side: +1 left of the travel, -1 right".into()),
        set("side", "{dy}*{wx}-{dx}*{wy}"),
        St::If("ABS({side}) LT 0.000000001".into(), vec![St::Stop(4, "initial contacts give no direction")], vec![]),
        set("side", "{side}/ABS({side})"),
        St::While(
            "{k} LT {maxn}".into(),
            vec![
                set("wx", "{qx}-{px}"),
                set("wy", "{qy}-{py}"),
                set("wl", "SQRT({wx}*{wx}+{wy}*{wy})"),
                St::If(
                    "{wl} GT 0.1*{rs}".into(),
                    vec![set("ux", "{wx}/{wl}"), set("uy", "{wy}/{wl}")],
                    vec![set("ux", "{qdy}*{side}"), set("uy", "-{qdx}*{side}")],
                ),
                set("nx", "-{uy}*{side}"),
                set("ny", "{ux}*{side}"),
                set("mx", "{qx}-{fx}"),
                set("my", "{qy}-{fy}"),
                St::If(
                    "{k} GE 4 AND {trav} GT 2.5*{rs} AND SQRT({mx}*{mx}+{my}*{my}) LT {rs} AND {nx}*{fdx}+{ny}*{fdy} GT 0"
                        .into(),
                    vec![St::Stop(1, "contour closed")],
                    vec![],
                ),
                St::Block(back_off("{qx}", "{qy}", "{qdx}", "{qdy}", "{qtl}")),
                set("hit", "0"),
                St::Guarded("{qx}+{ux}*{rs}-{nx}*{ro}".into(), "{qy}+{uy}*{rs}-{ny}*{ro}".into(), false),
                after_touch(vec![
                        set("ex", "{qx}+{ux}*{rs}+{nx}*{rs}"),
                        set("ey", "{qy}+{uy}*{rs}+{ny}*{rs}"),
                        St::Guarded("{ex}".into(), "{ey}".into(), false),
                        after_touch(vec![
                            St::Guarded("{ex}-{ux}*({rs}+{ro})".into(), "{ey}-{uy}*({rs}+{ro})".into(), false),
                            after_touch(vec![St::Guarded("{qx}".into(), "{qy}".into(), false)]),
                        ]),
                    ]),
                St::If("{hit} EQ 0".into(), vec![St::Stop(3, "lost surface")], vec![]),
                St::Record,
                set("wx", "{cx}-{qx}"),
                set("wy", "{cy}-{qy}"),
                set("trav", "{trav}+SQRT({wx}*{wx}+{wy}*{wy})"),
                set("px", "{qx}"),
                set("py", "{qy}"),
                set("qx", "{cx}"),
                set("qy", "{cy}"),
                set("qdx", "{hdx}"),
                set("qdy", "{hdy}"),
                set("qtl", "{tl}"),
            ],
        ),
        St::Stop(2, "contact limit reached"),
    ]
}

struct Writer {
    d: Dialect,
    out: String,
    label: u32,
    indent: usize,
}

impl Writer {
    fn var(&self, name: &str) -> String {
        let i = VARS.iter().position(|v| *v == name).unwrap_or(0);
        match self.d {
            Dialect::Iso => format!("#<{name}>"),
            Dialect::Pmac => format!("P{}", 1000 + i),
        }
    }

    /// Translate a neutral expression.
    fn expr(&self, e: &str) -> String {
        let mut s = String::new();
        let mut rest = e;
        while let Some(i) = rest.find('{') {
            s.push_str(&rest[..i]);
            let j = rest[i..].find('}').map(|j| i + j).unwrap_or(rest.len() - 1);
            s.push_str(&self.var(&rest[i + 1..j]));
            rest = &rest[j + 1..];
        }
        s.push_str(rest);
        match self.d {
            Dialect::Iso => s.replace('(', "[").replace(')', "]"),
            Dialect::Pmac => s
                .replace(" GE ", " !< ")
                .replace(" GT ", " > ")
                .replace(" LT ", " < ")
                .replace(" EQ ", " = "),
        }
    }

    fn line(&mut self, s: &str) {
        for _ in 0..self.indent {
            self.out.push_str("  ");
        }
        self.out.push_str(s);
        self.out.push('\n');
    }

    fn note(&mut self, s: &str) {
        match self.d {
            // RS274NGC comments do not nest.
            Dialect::Iso => self.line(&format!("({})", s.replace('(', "[").replace(')', "]"))),
            Dialect::Pmac => self.line(&format!("; {s}")),
        }
    }

    fn assign(&mut self, v: &str, e: &str) {
        let l = format!("{} = {}", self.var(v), self.paren(e));
        self.line(&l);
    }

    fn paren(&self, e: &str) -> String {
        match self.d {
            Dialect::Iso => format!("[{}]", self.expr(e)),
            Dialect::Pmac => format!("({})", self.expr(e)),
        }
    }

    fn guarded(&mut self, x: &str, y: &str, must: bool) {
        self.assign("ex", x);
        self.assign("ey", y);
        let (ex, ey) = (self.var("ex"), self.var("ey"));
        // Direction of this move, for the touch's record.
        match self.d {
            Dialect::Iso => {
                let (mx, my, ml) = (self.var("mx"), self.var("my"), self.var("ml"));
                let (cx, cy) = (self.var("cx"), self.var("cy"));
                self.line(&format!("{mx} = [{ex}-{cx}]"));
                self.line(&format!("{my} = [{ey}-{cy}]"));
                self.line(&format!("{ml} = SQRT[{mx}*{mx}+{my}*{my}]"));
                let g = if must { "G38.2" } else { "G38.3" };
                self.line(&format!("{g} X{ex} Y{ey}"));
                let hit = self.var("hit");
                if must {
                    self.line(&format!("{hit} = 1"));
                } else {
                    self.line(&format!("{hit} = #5070"));
                }
                let (hdx, hdy) = (self.var("hdx"), self.var("hdy"));
                // Where it stopped: the trip position after a touch, the
                // end of the move otherwise (the program keeps the position
                // itself rather than trusting what the control reports
                // after a probe move).
                self.line(&format!("{cx} = [#5061*{hit}+{ex}*[1-{hit}]]"));
                self.line(&format!("{cy} = [#5062*{hit}+{ey}*[1-{hit}]]"));
                self.line(&format!("{hdx} = [{mx}/{ml}]"));
                self.line(&format!("{hdy} = [{my}/{ml}]"));
                let tl = self.var("tl");
                self.line(&format!("{tl} = SQRT[[{cx}-{ex}+{mx}]**2+[{cy}-{ey}+{my}]**2]"));
            }
            Dialect::Pmac => {
                let (mx, my, ml) = (self.var("mx"), self.var("my"), self.var("ml"));
                let (cx, cy) = (self.var("cx"), self.var("cy"));
                self.line(&format!("{mx} = {ex}-{cx}"));
                self.line(&format!("{my} = {ey}-{cy}"));
                self.line(&format!("{ml} = SQRT({mx}*{mx}+{my}*{my})"));
                self.line(&format!("X({ex})^0 Y({ey})^0"));
                self.line("PMATCH");
                self.line(&format!("{cx} = M162/(I108*32*P999)"));
                self.line(&format!("{cy} = M262/(I208*32*P999)"));
                let hit = self.var("hit");
                let (hdx, hdy) = (self.var("hdx"), self.var("hdy"));
                self.line(&format!("{hit} = 0"));
                self.line(&format!("IF (ABS({cx}-{ex})+ABS({cy}-{ey}) > P998)"));
                self.line(&format!("  {hit} = 1"));
                self.line("ENDIF");
                self.line(&format!("{hdx} = {mx}/{ml}"));
                self.line(&format!("{hdy} = {my}/{ml}"));
                let tl = self.var("tl");
                self.line(&format!(
                    "{tl} = SQRT(({cx}-{ex}+{mx})*({cx}-{ex}+{mx})+({cy}-{ey}+{my})*({cy}-{ey}+{my}))"
                ));
                if must {
                    self.line(&format!("IF ({hit} = 0)"));
                    self.indent += 1;
                    self.stop(4, "no surface within the maximum approach");
                    self.indent -= 1;
                    self.line("ENDIF");
                }
            }
        }
    }

    fn plain_move(&mut self, x: &str, y: &str) {
        self.assign("ex", x);
        self.assign("ey", y);
        let (ex, ey, cx, cy) = (self.var("ex"), self.var("ey"), self.var("cx"), self.var("cy"));
        match self.d {
            Dialect::Iso => self.line(&format!("G1 X{ex} Y{ey}")),
            Dialect::Pmac => self.line(&format!("X({ex}) Y({ey})")),
        }
        self.line(&format!("{cx} = {ex}"));
        self.line(&format!("{cy} = {ey}"));
    }

    fn stop(&mut self, code: u32, why: &str) {
        match self.d {
            Dialect::Iso => {
                self.line(&format!("(MSG,probescan: {why})"));
                self.line("M5");
                self.line("(LOGCLOSE)");
                self.line("M2");
            }
            Dialect::Pmac => {
                self.line(&format!("P997 = {code} ; {why}"));
                self.line("RETURN");
            }
        }
    }

    fn record(&mut self) {
        let (k, cx, cy) = (self.var("k"), self.var("cx"), self.var("cy"));
        match self.d {
            Dialect::Iso => self.line(&format!("(LOG,{k} {cx} {cy})")),
            Dialect::Pmac => {
                self.line(&format!("P(2000+2*{k}) = {cx}"));
                self.line(&format!("P(2001+2*{k}) = {cy}"));
                self.line(&format!("P996 = {k}+1"));
            }
        }
        self.line(&format!("{k} = {}", self.paren("{k}+1")));
    }

    fn block(&mut self, sts: &[St]) {
        for s in sts {
            match s {
                St::Note(t) => self.note(t),
                St::Set(v, e) => self.assign(v, e),
                St::Guarded(x, y, must) => self.guarded(x, y, *must),
                St::Record => self.record(),
                St::Block(b) => self.block(b),
                St::Move(x, y) => self.plain_move(x, y),
                St::Stop(c, why) => self.stop(*c, why),
                St::If(c, a, b) => {
                    self.label += 1;
                    let l = 100 + self.label;
                    let c = self.expr(c);
                    match self.d {
                        Dialect::Iso => self.line(&format!("o{l} if [{c}]")),
                        Dialect::Pmac => self.line(&format!("IF ({c})")),
                    }
                    self.indent += 1;
                    self.block(a);
                    self.indent -= 1;
                    if !b.is_empty() {
                        match self.d {
                            Dialect::Iso => self.line(&format!("o{l} else")),
                            Dialect::Pmac => self.line("ELSE"),
                        }
                        self.indent += 1;
                        self.block(b);
                        self.indent -= 1;
                    }
                    match self.d {
                        Dialect::Iso => self.line(&format!("o{l} endif")),
                        Dialect::Pmac => self.line("ENDIF"),
                    }
                }
                St::While(c, body) => {
                    self.label += 1;
                    let l = 100 + self.label;
                    let c = self.expr(c);
                    match self.d {
                        Dialect::Iso => self.line(&format!("o{l} while [{c}]")),
                        Dialect::Pmac => self.line(&format!("WHILE ({c})")),
                    }
                    self.indent += 1;
                    self.block(body);
                    self.indent -= 1;
                    match self.d {
                        Dialect::Iso => self.line(&format!("o{l} endwhile")),
                        Dialect::Pmac => self.line("ENDWHILE"),
                    }
                }
            }
        }
    }
}

/// The probing program for `params` with `probe` in dialect `d`.
pub fn write(d: Dialect, probe: &Probe, params: &ScanParams, machine: &ControllerSettings) -> String {
    let mut w = Writer {
        d,
        out: String::new(),
        label: 0,
        indent: 0,
    };
    let num = |x: f64| {
        let mut s = String::new();
        crate::formats::push_num(&mut s, x);
        s
    };
    let fmin = num(probe.feed_mm_s * 60.0);
    let head = [
        "probescan: automated XY scan with a rotating wire probe (Bayesteh 2013, ch. 4)".to_string(),
        format!(
            "D_e {} mm, {} rpm, approach {} mm/s: touch resolution {} mm",
            num(probe.effective_diameter_mm),
            num(probe.rpm),
            num(probe.feed_mm_s),
            num(probe.touch_resolution_mm())
        ),
        "contacts are probe centres: the surface lies D_e/2 beyond them".to_string(),
    ];
    match d {
        Dialect::Iso => {
            for h in &head {
                w.note(h);
            }
            w.note("G38.2/G38.3 stop on the probe input (the AE detector); #5070 = touched, #5061/#5062 = where");
            w.line("(LOGOPEN,probescan-contacts.txt)");
            w.line("G21 G17 G90 G94");
            w.line(&format!("F{fmin}"));
            w.line(&format!("M3 S{}", num(probe.rpm)));
            w.line("G4 P2");
            w.line(&format!("G0 X{} Y{}", num(params.start.x), num(params.start.y)));
            w.line(&format!("{} = {}", w.var("cx"), num(params.start.x)));
            w.line(&format!("{} = {}", w.var("cy"), num(params.start.y)));
        }
        Dialect::Pmac => {
            for h in &head {
                w.note(h);
            }
            w.note("Setup: the AE detector's threshold output on the capture flag of motors 1 (X) and 2 (Y);");
            w.note("Ixx97 = 0 (input trigger, hardware capture); I7mn2/I7mn3 select that flag's rising edge.");
            w.note("Contacts: P996 of them, X and Y (mm) in P2000, P2001, P2002...; P997 = 1 closed,");
            w.note("2 contact limit, 3 lost surface, 4 no surface / bad start.");
            w.line("CLOSE");
            w.line("M162->D:$00008B ; motor 1 actual position (1/[I108*32] counts)");
            w.line("M262->D:$00010B ; motor 2 actual position");
            w.line(&format!("P999 = {} ; counts per mm", num(machine.counts_per_mm)));
            w.line("P998 = 0.0005 ; a move that stops this far short of its end touched (mm)");
            w.line(&format!("OPEN PROG {} CLEAR", machine.prog));
            w.line("ABS RAPID");
            w.note("move-until-trigger runs at the jog speed: the approach feed in counts/ms");
            let cpm = num(probe.feed_mm_s * machine.counts_per_mm / 1000.0);
            w.line(&format!("I122 = {cpm}"));
            w.line(&format!("I222 = {cpm}"));
            w.note(&format!("the spindle must already turn at {} rpm", num(probe.rpm)));
            w.line("P996 = 0");
            w.line(&format!("X{} Y{}", num(params.start.x), num(params.start.y)));
            // The current position, for the first move's direction.
            w.line(&format!("{} = {}", w.var("cx"), num(params.start.x)));
            w.line(&format!("{} = {}", w.var("cy"), num(params.start.y)));
        }
    }
    w.block(&algorithm(params, params.max_points));
    if d == Dialect::Pmac {
        w.line("CLOSE");
    }
    w.out
}
