//! Specialisation of a kernel's SPIR-V before the driver sees it.
//!
//! The kernels are compiled once, at build time, with every effect behind a
//! specialisation constant (`SPEC_*`), and the scene's values are only known
//! when its pipelines are built. A driver applies the values, but only after
//! it has translated the whole module: lavapipe turns all of it into NIR
//! before its dead-code passes remove what the values switch off, and that
//! translation grows with every effect the kernels can do, not with what the
//! scene uses (the shade kernel's module is fully inlined and over a
//! megabyte). So [`specialise`] does the part that needs no optimiser: it
//! turns the given specialisation constants into plain constants, evaluates
//! the integer and boolean instructions whose operands are all constant
//! (phis over the edges still taken included), points each branch that a
//! known condition never takes at its construct's merge block (so the
//! structured control flow stays valid, and what only that branch led to
//! becomes unreachable), and deletes the blocks no path reaches.
//! The code that remains is exactly the code the driver would have kept, so
//! images do not change; only the work the driver does to build the
//! pipeline shrinks.
//!
//! The transform is conservative: it leaves loops' own branches alone, and
//! it returns a function unchanged when a loop's continue block would
//! become unreachable (a case that would need undefined values in the loop
//! header's phis).

use std::collections::{HashMap, HashSet};

/// SPIR-V's magic number, the first word of every module.
const MAGIC: u32 = 0x0723_0203;
/// Words in a module's header.
const HEADER_WORDS: usize = 5;

// The opcodes the transform reads or writes (SPIR-V 1.6 unified spec).
const OP_UNDEF: u32 = 1;
const OP_NAME: u32 = 5;
const OP_TYPE_BOOL: u32 = 20;
const OP_TYPE_INT: u32 = 21;
const OP_CONSTANT_TRUE: u32 = 41;
const OP_CONSTANT_FALSE: u32 = 42;
const OP_CONSTANT: u32 = 43;
const OP_SPEC_CONSTANT_TRUE: u32 = 48;
const OP_SPEC_CONSTANT_FALSE: u32 = 49;
const OP_SPEC_CONSTANT: u32 = 50;
const OP_SPEC_CONSTANT_OP: u32 = 52;
const OP_FUNCTION: u32 = 54;
const OP_FUNCTION_END: u32 = 56;
const OP_DECORATE: u32 = 71;
const OP_COPY_OBJECT: u32 = 83;
const OP_IADD: u32 = 128;
const OP_ISUB: u32 = 130;
const OP_IMUL: u32 = 132;
const OP_LOGICAL_EQUAL: u32 = 164;
const OP_LOGICAL_NOT_EQUAL: u32 = 165;
const OP_LOGICAL_OR: u32 = 166;
const OP_LOGICAL_AND: u32 = 167;
const OP_LOGICAL_NOT: u32 = 168;
const OP_SELECT: u32 = 169;
const OP_IEQUAL: u32 = 170;
const OP_INOT_EQUAL: u32 = 171;
const OP_UGREATER_THAN: u32 = 172;
const OP_UGREATER_THAN_EQUAL: u32 = 174;
const OP_ULESS_THAN: u32 = 176;
const OP_ULESS_THAN_EQUAL: u32 = 178;
const OP_SHIFT_RIGHT_LOGICAL: u32 = 194;
const OP_SHIFT_LEFT_LOGICAL: u32 = 196;
const OP_BITWISE_OR: u32 = 197;
const OP_BITWISE_XOR: u32 = 198;
const OP_BITWISE_AND: u32 = 199;
const OP_NOT: u32 = 200;
const OP_PHI: u32 = 245;
const OP_LOOP_MERGE: u32 = 246;
const OP_SELECTION_MERGE: u32 = 247;
const OP_LABEL: u32 = 248;
const OP_BRANCH: u32 = 249;
const OP_BRANCH_CONDITIONAL: u32 = 250;
const OP_SWITCH: u32 = 251;
const OP_UNREACHABLE: u32 = 255;
/// `Decoration::SpecId`.
const DECORATION_SPEC_ID: u32 = 1;

/// One instruction: its words, the first holding word count and opcode.
type Inst = Vec<u32>;

/// The opcode of an instruction.
fn opcode(inst: &[u32]) -> u32 {
    inst[0] & 0xFFFF
}

/// Builds an instruction from its opcode and operands.
fn inst(op: u32, operands: &[u32]) -> Inst {
    let mut words = Vec::with_capacity(operands.len() + 1);
    words.push(((operands.len() as u32 + 1) << 16) | op);
    words.extend_from_slice(operands);
    words
}

/// A value the transform knows: a boolean or a 32-bit integer's bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Value {
    Bool(bool),
    Int(u32),
}

/// A basic block: its label and its instructions after the label.
struct Block {
    label: u32,
    body: Vec<Inst>,
}

impl Block {
    /// The block's terminator (its last instruction).
    fn terminator(&self) -> &Inst {
        self.body.last().expect("a block ends in a terminator")
    }

    /// The merge instruction just before the terminator, if any.
    fn merge(&self) -> Option<&Inst> {
        let n = self.body.len();
        (n >= 2)
            .then(|| &self.body[n - 2])
            .filter(|i| matches!(opcode(i), OP_SELECTION_MERGE | OP_LOOP_MERGE))
    }

    /// The labels the terminator can branch to.
    fn successors(&self) -> Vec<u32> {
        let t = self.terminator();
        match opcode(t) {
            OP_BRANCH => vec![t[1]],
            OP_BRANCH_CONDITIONAL => vec![t[2], t[3]],
            // Selector, default, then (literal, label) pairs of one-word literals
            OP_SWITCH => {
                let mut out = vec![t[2]];
                out.extend(t[3..].chunks(2).filter_map(|c| c.get(1).copied()));
                out
            }
            _ => Vec::new(),
        }
    }
}

/// A function: its header instructions (`OpFunction` and parameters), blocks
/// and `OpFunctionEnd`.
struct Function {
    head: Vec<Inst>,
    blocks: Vec<Block>,
    end: Inst,
}

/// Specialises `words`, a SPIR-V module, to the specialisation constants in
/// `values` (`(SpecId, value)`, each a 32-bit word as Vulkan's map gives it):
/// each becomes a plain constant, and the code its value switches off is
/// deleted (see the module's doc). Constants not in `values` stay
/// specialisation constants. A module this does not understand (no magic
/// number, a truncated instruction, a function without blocks) is returned
/// unchanged, for the driver to judge.
pub fn specialise(words: &[u32], values: &[(u32, u32)]) -> Vec<u32> {
    parse(words)
        .map(|module| module.specialise(values))
        .unwrap_or_else(|| words.to_vec())
}

/// The words of a SPIR-V module stored as little-endian bytes (a trailing
/// partial word is dropped, for [`specialise`] to refuse the module).
pub fn words_of(bytes: &[u8]) -> Vec<u32> {
    bytes
        .chunks_exact(4)
        .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
        .collect()
}

/// A module split into its header, the instructions before the first
/// function, and its functions.
struct Module {
    header: Vec<u32>,
    preamble: Vec<Inst>,
    functions: Vec<Function>,
}

/// Splits a module into instructions, blocks and functions; `None` if it is
/// not well-formed enough to transform.
fn parse(words: &[u32]) -> Option<Module> {
    if words.len() < HEADER_WORDS || words[0] != MAGIC {
        return None;
    }
    let mut insts = Vec::new();
    let mut at = HEADER_WORDS;
    while at < words.len() {
        let count = (words[at] >> 16) as usize;
        if count == 0 || at + count > words.len() {
            return None;
        }
        insts.push(words[at..at + count].to_vec());
        at += count;
    }
    let mut preamble = Vec::new();
    let mut functions = Vec::new();
    let mut iter = insts.into_iter().peekable();
    while let Some(i) = iter.next() {
        if opcode(&i) != OP_FUNCTION {
            if functions.is_empty() {
                preamble.push(i);
                continue;
            }
            return None; // nothing but functions follows the first one
        }
        let mut head = vec![i];
        while iter
            .peek()
            .is_some_and(|i| opcode(i) != OP_LABEL && opcode(i) != OP_FUNCTION_END)
        {
            head.push(iter.next()?);
        }
        let mut blocks: Vec<Block> = Vec::new();
        let end = loop {
            let i = iter.next()?;
            match opcode(&i) {
                OP_FUNCTION_END => break i,
                OP_LABEL => blocks.push(Block {
                    label: *i.get(1)?,
                    body: Vec::new(),
                }),
                _ => blocks.last_mut()?.body.push(i),
            }
        };
        if blocks.is_empty() || blocks.iter().any(|b| b.body.is_empty()) {
            return None;
        }
        functions.push(Function { head, blocks, end });
    }
    Some(Module {
        header: words[..HEADER_WORDS].to_vec(),
        preamble,
        functions,
    })
}

impl Module {
    /// Applies the transform and writes the module back out.
    fn specialise(mut self, values: &[(u32, u32)]) -> Vec<u32> {
        let by_spec_id: HashMap<u32, u32> = values.iter().copied().collect();
        let mut known = self.fold_constants(&by_spec_id);
        let mut removed: HashSet<u32> = HashSet::new();
        let mut undefs = Undefs {
            bound: self.header[3],
            by_type: Vec::new(),
        };
        for f in &mut self.functions {
            f.fold(&mut known, &mut removed, &mut undefs);
        }
        // The undefined values of never-taken edges, among the global values
        self.header[3] = undefs.bound;
        for &(ty, id) in &undefs.by_type {
            self.preamble.push(inst(OP_UNDEF, &[ty, id]));
        }
        // Names and decorations of deleted ids go with them
        self.preamble
            .retain(|i| !(matches!(opcode(i), OP_NAME | OP_DECORATE) && removed.contains(&i[1])));
        let mut out = self.header;
        for i in &self.preamble {
            out.extend_from_slice(i);
        }
        for f in &self.functions {
            for i in &f.head {
                out.extend_from_slice(i);
            }
            for b in &f.blocks {
                out.extend_from_slice(&inst(OP_LABEL, &[b.label]));
                for i in &b.body {
                    out.extend_from_slice(i);
                }
            }
            out.extend_from_slice(&f.end);
        }
        out
    }

    /// Turns the specialisation constants named in `by_spec_id` into plain
    /// constants, evaluates the specialisation-constant operations whose
    /// operands are then known, and returns every known constant by id.
    fn fold_constants(&mut self, by_spec_id: &HashMap<u32, u32>) -> HashMap<u32, Value> {
        let mut spec_id_of: HashMap<u32, u32> = HashMap::new();
        let mut int32: HashSet<u32> = HashSet::new();
        let mut bool_type: HashSet<u32> = HashSet::new();
        for i in &self.preamble {
            match opcode(i) {
                OP_DECORATE if i.get(2) == Some(&DECORATION_SPEC_ID) && i.len() == 4 => {
                    spec_id_of.insert(i[1], i[3]);
                }
                OP_TYPE_INT if i.get(2) == Some(&32) => {
                    int32.insert(i[1]);
                }
                OP_TYPE_BOOL => {
                    bool_type.insert(i[1]);
                }
                _ => {}
            }
        }
        let mut known: HashMap<u32, Value> = HashMap::new();
        let mut folded: HashSet<u32> = HashSet::new();
        for i in &mut self.preamble {
            let op = opcode(i);
            let value_of_spec = |id: u32| spec_id_of.get(&id).and_then(|s| by_spec_id.get(s));
            match op {
                OP_CONSTANT_TRUE | OP_CONSTANT_FALSE => {
                    known.insert(i[2], Value::Bool(op == OP_CONSTANT_TRUE));
                }
                OP_CONSTANT if i.len() == 4 && int32.contains(&i[1]) => {
                    known.insert(i[2], Value::Int(i[3]));
                }
                OP_SPEC_CONSTANT_TRUE | OP_SPEC_CONSTANT_FALSE => {
                    if let Some(&v) = value_of_spec(i[2]) {
                        let op = if v != 0 {
                            OP_CONSTANT_TRUE
                        } else {
                            OP_CONSTANT_FALSE
                        };
                        *i = inst(op, &[i[1], i[2]]);
                        known.insert(i[2], Value::Bool(v != 0));
                        folded.insert(i[2]);
                    }
                }
                OP_SPEC_CONSTANT if i.len() == 4 && int32.contains(&i[1]) => {
                    if let Some(&v) = value_of_spec(i[2]) {
                        *i = inst(OP_CONSTANT, &[i[1], i[2], v]);
                        known.insert(i[2], Value::Int(v));
                        folded.insert(i[2]);
                    }
                }
                OP_SPEC_CONSTANT_OP if i.len() >= 4 => {
                    let (ty, id) = (i[1], i[2]);
                    let Some(v) = evaluate(i[3], &i[4..], &known) else {
                        continue;
                    };
                    *i = match v {
                        Value::Bool(b) if bool_type.contains(&ty) => inst(
                            if b {
                                OP_CONSTANT_TRUE
                            } else {
                                OP_CONSTANT_FALSE
                            },
                            &[ty, id],
                        ),
                        Value::Int(n) if int32.contains(&ty) => inst(OP_CONSTANT, &[ty, id, n]),
                        _ => continue,
                    };
                    known.insert(id, v);
                }
                _ => {}
            }
        }
        // A plain constant carries no SpecId
        self.preamble.retain(|i| {
            !(opcode(i) == OP_DECORATE
                && i.get(2) == Some(&DECORATION_SPEC_ID)
                && folded.contains(&i[1]))
        });
        known
    }
}

/// Evaluates operation `op` on operand ids `args` when every operand it
/// reads is known; `None` otherwise, or for an operation the transform does
/// not evaluate. Integer arithmetic wraps, as SPIR-V's does.
fn evaluate(op: u32, args: &[u32], known: &HashMap<u32, Value>) -> Option<Value> {
    let get = |k: usize| args.get(k).and_then(|id| known.get(id)).copied();
    let boolean = |k: usize| match get(k) {
        Some(Value::Bool(b)) => Some(b),
        _ => None,
    };
    let int = |k: usize| match get(k) {
        Some(Value::Int(n)) => Some(n),
        _ => None,
    };
    let int2 = || Some((int(0)?, int(1)?));
    Some(match op {
        OP_COPY_OBJECT => get(0)?,
        OP_LOGICAL_NOT => Value::Bool(!boolean(0)?),
        OP_LOGICAL_EQUAL => Value::Bool(boolean(0)? == boolean(1)?),
        OP_LOGICAL_NOT_EQUAL => Value::Bool(boolean(0)? != boolean(1)?),
        // An operand that decides the result alone decides it unknown or not
        OP_LOGICAL_AND => match (boolean(0), boolean(1)) {
            (Some(false), _) | (_, Some(false)) => Value::Bool(false),
            (Some(a), Some(b)) => Value::Bool(a && b),
            _ => return None,
        },
        OP_LOGICAL_OR => match (boolean(0), boolean(1)) {
            (Some(true), _) | (_, Some(true)) => Value::Bool(true),
            (Some(a), Some(b)) => Value::Bool(a || b),
            _ => return None,
        },
        OP_SELECT => get(if boolean(0)? { 1 } else { 2 })?,
        OP_IEQUAL => int2().map(|(a, b)| Value::Bool(a == b))?,
        OP_INOT_EQUAL => int2().map(|(a, b)| Value::Bool(a != b))?,
        OP_UGREATER_THAN => int2().map(|(a, b)| Value::Bool(a > b))?,
        OP_UGREATER_THAN_EQUAL => int2().map(|(a, b)| Value::Bool(a >= b))?,
        OP_ULESS_THAN => int2().map(|(a, b)| Value::Bool(a < b))?,
        OP_ULESS_THAN_EQUAL => int2().map(|(a, b)| Value::Bool(a <= b))?,
        OP_IADD => int2().map(|(a, b)| Value::Int(a.wrapping_add(b)))?,
        OP_ISUB => int2().map(|(a, b)| Value::Int(a.wrapping_sub(b)))?,
        OP_IMUL => int2().map(|(a, b)| Value::Int(a.wrapping_mul(b)))?,
        OP_BITWISE_AND => int2().map(|(a, b)| Value::Int(a & b))?,
        OP_BITWISE_OR => int2().map(|(a, b)| Value::Int(a | b))?,
        OP_BITWISE_XOR => int2().map(|(a, b)| Value::Int(a ^ b))?,
        OP_NOT => Value::Int(!int(0)?),
        // Shifts by the width or more are undefined in SPIR-V: left alone
        OP_SHIFT_LEFT_LOGICAL => int2().and_then(|(a, s)| a.checked_shl(s)).map(Value::Int)?,
        OP_SHIFT_RIGHT_LOGICAL => int2().and_then(|(a, s)| a.checked_shr(s)).map(Value::Int)?,
        _ => return None,
    })
}

/// The `OpUndef` values the transform adds, one per type, and the module's
/// id bound they are taken from.
struct Undefs {
    bound: u32,
    by_type: Vec<(u32, u32)>,
}

impl Undefs {
    /// The undefined value of type `ty`.
    fn of(&mut self, ty: u32) -> u32 {
        if let Some(&(_, id)) = self.by_type.iter().find(|(t, _)| *t == ty) {
            return id;
        }
        let id = self.bound;
        self.bound += 1;
        self.by_type.push((ty, id));
        id
    }

    /// Whether `id` is one of these undefined values.
    fn contains(&self, id: u32) -> bool {
        self.by_type.iter().any(|&(_, u)| u == id)
    }
}

impl Function {
    /// Folds branches on known conditions until nothing changes, then
    /// deletes the blocks no path reaches; ids defined in deleted blocks go
    /// into `removed`. Leaves the function as it was if a reachable loop
    /// would lose its continue block.
    fn fold(
        &mut self,
        known: &mut HashMap<u32, Value>,
        removed: &mut HashSet<u32>,
        undefs: &mut Undefs,
    ) {
        let original: Vec<(u32, Vec<Inst>)> = self
            .blocks
            .iter()
            .map(|b| (b.label, b.body.clone()))
            .collect();
        let mut reachable = self.reachable();
        loop {
            self.evaluate(known, &reachable, undefs);
            let changed = self.fold_branches(known, &reachable, undefs);
            reachable = self.reachable();
            self.prune_phis(&reachable);
            if !changed {
                break;
            }
        }
        // Blocks a reachable merge instruction names stay, as placeholders
        let mut merges = HashSet::new();
        let mut continues = HashSet::new();
        for b in self.blocks.iter().filter(|b| reachable.contains(&b.label)) {
            if let Some(m) = b.merge() {
                merges.insert(m[1]);
                if opcode(m) == OP_LOOP_MERGE {
                    continues.insert(m[2]);
                }
            }
        }
        if continues.iter().any(|c| !reachable.contains(c)) {
            for (b, (label, body)) in self.blocks.iter_mut().zip(original) {
                b.label = label;
                b.body = body;
            }
            return;
        }
        self.blocks.retain_mut(|b| {
            if reachable.contains(&b.label) {
                return true;
            }
            removed.extend(b.body.iter().filter_map(|i| result_id(i)));
            if merges.contains(&b.label) {
                b.body = vec![inst(OP_UNREACHABLE, &[])];
                return true;
            }
            removed.insert(b.label);
            false
        });
    }

    /// Records the value of every instruction of a reachable block whose
    /// operands are known, phis included (over their incoming edges).
    fn evaluate(&self, known: &mut HashMap<u32, Value>, reachable: &HashSet<u32>, undefs: &Undefs) {
        for b in self.blocks.iter().filter(|b| reachable.contains(&b.label)) {
            for i in &b.body {
                let op = opcode(i);
                if op == OP_PHI {
                    // (value, parent) pairs after the type and result; an
                    // undefined value comes over an edge never taken
                    let mut values = i[3..]
                        .chunks(2)
                        .filter(|c| !undefs.contains(c[0]))
                        .map(|c| known.get(&c[0]).copied());
                    let first = values.next().flatten();
                    if let Some(v) = first.filter(|v| values.all(|w| w == Some(*v))) {
                        known.insert(i[2], v);
                    }
                    continue;
                }
                if has_type_and_result(op) && i.len() >= 3 {
                    if let Some(v) = evaluate(op, &i[3..], known) {
                        known.insert(i[2], v);
                    }
                }
            }
        }
    }

    /// Points every branch of a reachable block that a known condition
    /// never takes at the block's selection merge instead (so the construct
    /// stays as it was, and what only that branch led to becomes
    /// unreachable), giving the merge's phis an undefined value over the new
    /// edge; a conditional branch without a merge instruction becomes a plain
    /// branch. A loop's branches are left alone. Returns whether any changed.
    fn fold_branches(
        &mut self,
        known: &HashMap<u32, Value>,
        reachable: &HashSet<u32>,
        undefs: &mut Undefs,
    ) -> bool {
        // (merge, header) pairs of the edges added
        let mut added: Vec<(u32, u32)> = Vec::new();
        for b in self
            .blocks
            .iter_mut()
            .filter(|b| reachable.contains(&b.label))
        {
            let merge = match b.merge() {
                Some(m) if opcode(m) == OP_LOOP_MERGE => continue,
                Some(m) => Some(m[1]),
                None => None,
            };
            let label = b.label;
            let n = b.body.len();
            let t = &mut b.body[n - 1];
            let cond = t.get(1).and_then(|c| known.get(c)).copied();
            match (opcode(t), cond, merge) {
                (OP_BRANCH_CONDITIONAL, Some(Value::Bool(c)), Some(m)) => {
                    let dead = if c { 3 } else { 2 };
                    if t[dead] != m {
                        t[dead] = m;
                        added.push((m, label));
                    }
                }
                (OP_BRANCH_CONDITIONAL, Some(Value::Bool(c)), None) => {
                    *t = inst(OP_BRANCH, &[if c { t[2] } else { t[3] }]);
                    added.push((0, 0));
                }
                (OP_SWITCH, Some(Value::Int(s)), Some(m)) => {
                    let live = t[3..]
                        .chunks(2)
                        .find(|c| c.len() == 2 && c[0] == s)
                        .map_or(t[2], |c| c[1]);
                    // The default, then each case's label
                    let slots = std::iter::once(2).chain((4..t.len()).step_by(2));
                    let mut changed = false;
                    for k in slots.collect::<Vec<_>>() {
                        if t[k] != live && t[k] != m {
                            t[k] = m;
                            changed = true;
                        }
                    }
                    if changed {
                        added.push((m, label));
                    }
                }
                _ => {}
            }
        }
        for &(m, header) in added.iter().filter(|(m, _)| *m != 0) {
            let Some(block) = self.blocks.iter_mut().find(|b| b.label == m) else {
                continue;
            };
            for i in block.body.iter_mut().filter(|i| opcode(i) == OP_PHI) {
                if !i[3..].chunks(2).any(|c| c.get(1) == Some(&header)) {
                    let undef = undefs.of(i[1]);
                    i.extend_from_slice(&[undef, header]);
                    i[0] = ((i.len() as u32) << 16) | OP_PHI;
                }
            }
        }
        !added.is_empty()
    }

    /// The labels of the blocks some path from the entry reaches.
    fn reachable(&self) -> HashSet<u32> {
        let by_label: HashMap<u32, &Block> = self.blocks.iter().map(|b| (b.label, b)).collect();
        let mut seen = HashSet::from([self.blocks[0].label]);
        let mut stack = vec![self.blocks[0].label];
        while let Some(l) = stack.pop() {
            for s in by_label.get(&l).map(|b| b.successors()).unwrap_or_default() {
                if seen.insert(s) {
                    stack.push(s);
                }
            }
        }
        seen
    }

    /// Keeps each phi's incoming pairs whose parent still branches to its
    /// block from a reachable block.
    fn prune_phis(&mut self, reachable: &HashSet<u32>) {
        let mut preds: HashMap<u32, HashSet<u32>> = HashMap::new();
        for b in self.blocks.iter().filter(|b| reachable.contains(&b.label)) {
            for s in b.successors() {
                preds.entry(s).or_default().insert(b.label);
            }
        }
        for b in &mut self.blocks {
            let Some(p) = preds.get(&b.label) else {
                continue;
            };
            for i in b.body.iter_mut().filter(|i| opcode(i) == OP_PHI) {
                let kept: Vec<u32> = i[3..]
                    .chunks(2)
                    .filter(|c| c.len() == 2 && p.contains(&c[1]))
                    .flatten()
                    .copied()
                    .collect();
                if kept.len() + 3 != i.len() {
                    *i = inst(OP_PHI, &[&i[1..3], &kept[..]].concat());
                }
            }
        }
    }
}

/// Whether instructions of opcode `op` start with a result type and id.
/// Only the opcodes [`evaluate`] reads and phis need to be right here.
fn has_type_and_result(op: u32) -> bool {
    matches!(
        op,
        OP_COPY_OBJECT
            | OP_IADD
            | OP_ISUB
            | OP_IMUL
            | OP_LOGICAL_EQUAL..=OP_ULESS_THAN_EQUAL
            | OP_SHIFT_RIGHT_LOGICAL..=OP_NOT
            | OP_PHI
    )
}

/// The result id an instruction in a block defines: the second operand,
/// after the result type, for every instruction that has one. The
/// instructions that may stand in a block without a result are listed.
fn result_id(i: &[u32]) -> Option<u32> {
    const NO_RESULT: &[u32] = &[
        0,   // OpNop
        8,   // OpLine
        317, // OpNoLine
        62,  // OpStore
        63,  // OpCopyMemory
        64,  // OpCopyMemorySized
        99,  // OpImageWrite
        224, // OpControlBarrier
        225, // OpMemoryBarrier
        228, // OpAtomicStore
        252, // OpKill
        253, // OpReturn
        254, // OpReturnValue
        256, // OpLifetimeStart
        257, // OpLifetimeStop
        OP_LOOP_MERGE,
        OP_SELECTION_MERGE,
        OP_BRANCH,
        OP_BRANCH_CONDITIONAL,
        OP_SWITCH,
        OP_UNREACHABLE,
        4416, // OpTerminateInvocation
        5380, // OpDemoteToHelperInvocation
    ];
    (!NO_RESULT.contains(&opcode(i)) && i.len() >= 3).then(|| i[2])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::kernels::{Features, Integrator, Pass};

    /// The words of a kernel's SPIR-V.
    fn words(pass: Pass) -> Vec<u32> {
        let bytes = pass.spirv(true);
        assert!(!bytes.is_empty(), "built without kernels");
        words_of(bytes)
    }

    /// Runs `spirv-val` (SPIRV-Tools, installed by scripts/setup.sh) on a
    /// module; panics with its message if the module is invalid or the tool
    /// is missing.
    fn validate(words: &[u32], what: &str) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("kernel.spv");
        std::fs::write(&path, bytemuck::cast_slice::<u32, u8>(words)).unwrap();
        let out = std::process::Command::new("spirv-val")
            .args(["--target-env", "vulkan1.2"])
            .arg(&path)
            .output()
            .expect("spirv-val (Debian package spirv-tools) runs; scripts/setup.sh installs it");
        assert!(
            out.status.success(),
            "{what}: {}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
    }

    /// Sets one boolean feature.
    type Switch = fn(&mut Features, bool);

    /// Setters of every boolean feature, by name.
    const SWITCHES: &[(&str, Switch)] = &[
        ("spheres", |f, v| f.spheres = v),
        ("triangles", |f, v| f.triangles = v),
        ("nee", |f, v| f.nee = v),
        ("emission", |f, v| f.emission = v),
        ("delta_lights", |f, v| f.delta_lights = v),
        ("path_flags", |f, v| f.path_flags = v),
        ("environment", |f, v| f.environment = v),
        ("envmap", |f, v| f.envmap = v),
        ("textures", |f, v| f.textures = v),
        ("texture_mapping", |f, v| f.texture_mapping = v),
        ("depth_of_field", |f, v| f.depth_of_field = v),
        ("pixel_filter", |f, v| f.pixel_filter = v),
        ("clip", |f, v| f.clip = v),
        ("film_edge", |f, v| f.film_edge = v),
        ("camera_shift", |f, v| f.camera_shift = v),
        ("orthographic", |f, v| f.orthographic = v),
        ("mask", |f, v| f.mask = v),
        ("normal_map", |f, v| f.normal_map = v),
        ("mesh_attributes", |f, v| f.mesh_attributes = v),
        ("shading_sides", |f, v| f.shading_sides = v),
        ("pixel_list", |f, v| f.pixel_list = v),
    ];

    /// Every feature on; every feature off but triangles, emission and
    /// next-event estimation over Lambert surfaces (the Cornell box); and
    /// each feature switched alone from each of the two.
    fn feature_sets() -> Vec<(String, Features)> {
        let all = Features::all(Integrator::Nee);
        let mut none = all;
        for (_, set) in SWITCHES {
            set(&mut none, false);
        }
        none.triangles = true;
        none.emission = true;
        none.nee = true;
        none.material_mask = 1 << crate::interface::MAT_LAMBERT;
        let mut out = vec![("all".to_string(), all), ("cornell".to_string(), none)];
        for (name, set) in SWITCHES {
            let mut on = none;
            set(&mut on, true);
            let mut off = all;
            set(&mut off, false);
            out.push((format!("cornell + {name}"), on));
            out.push((format!("all - {name}"), off));
        }
        out
    }

    /// Every pass specialised for every feature set is valid SPIR-V. A
    /// feature set that leaves a pass's module the same word for word as
    /// another set did is the same module: each distinct module is
    /// validated once, named by the first set that made it, and the
    /// distinct modules are validated in parallel.
    #[test]
    fn specialised_kernels_are_valid_spirv_for_every_feature_set() {
        use rayon::prelude::*;
        let mut distinct: HashMap<Vec<u32>, String> = HashMap::new();
        let mut made = 0;
        for pass in Pass::ALL {
            let w = words(pass);
            for (name, features) in feature_sets() {
                let out = specialise(&w, &features.spec_constants(pass));
                made += 1;
                distinct
                    .entry(out)
                    .or_insert_with(|| format!("{} kernel, {name}", pass.name()));
            }
        }
        println!("{made} specialised kernels, {} distinct", distinct.len());
        distinct
            .par_iter()
            .for_each(|(module, what)| validate(module, what));
    }

    /// The Cornell box's shade kernel and megakernel keep 15% and 19% of
    /// their words (310,782 to 47,974, 336,723 to 65,598, when measured);
    /// with every feature on, over 90% of every kernel is live (an adaptive
    /// render's pixel list and the shadow kernel's occlusion stay off).
    #[test]
    fn specialising_keeps_only_what_the_features_use() {
        let sets = feature_sets();
        let (all, cornell) = (sets[0].1, sets[1].1);
        for pass in Pass::ALL {
            let w = words(pass);
            let kept = |f: &Features| specialise(&w, &f.spec_constants(pass)).len() as f64;
            let n = w.len() as f64;
            assert!(
                kept(&all) > 0.9 * n,
                "{}: {} of {n}",
                pass.name(),
                kept(&all)
            );
            if matches!(pass, Pass::Shade | Pass::Megakernel) {
                let k = kept(&cornell);
                assert!(k < 0.25 * n, "{}: {k} of {n}", pass.name());
            }
        }
    }

    #[test]
    fn a_module_it_cannot_read_is_returned_unchanged() {
        let truncated = [MAGIC, 0x0001_0500, 0, 100, 0, (4 << 16) | OP_NAME, 1];
        assert_eq!(specialise(&truncated, &[(0, 1)]), truncated);
        let not_spirv = [1, 2, 3, 4, 5, 6];
        assert_eq!(specialise(&not_spirv, &[(0, 1)]), not_spirv);
    }

    #[test]
    fn constants_fold_as_spirv_defines_them() {
        let known: HashMap<u32, Value> = [
            (1, Value::Bool(true)),
            (2, Value::Bool(false)),
            (3, Value::Int(6)),
            (4, Value::Int(3)),
            (5, Value::Int(40)),
        ]
        .into();
        let e = |op, args: &[u32]| evaluate(op, args, &known);
        // An unknown operand (9) decides nothing unless the other decides all
        assert_eq!(e(OP_LOGICAL_AND, &[2, 9]), Some(Value::Bool(false)));
        assert_eq!(e(OP_LOGICAL_AND, &[1, 9]), None);
        assert_eq!(e(OP_LOGICAL_OR, &[9, 1]), Some(Value::Bool(true)));
        assert_eq!(e(OP_LOGICAL_NOT, &[2]), Some(Value::Bool(true)));
        assert_eq!(e(OP_SELECT, &[2, 3, 4]), Some(Value::Int(3)));
        assert_eq!(e(OP_BITWISE_AND, &[3, 4]), Some(Value::Int(2)));
        assert_eq!(e(OP_INOT_EQUAL, &[3, 4]), Some(Value::Bool(true)));
        assert_eq!(e(OP_ISUB, &[4, 3]), Some(Value::Int(u32::MAX - 2)));
        assert_eq!(e(OP_SHIFT_LEFT_LOGICAL, &[4, 3]), Some(Value::Int(192)));
        // Shifting by the width or more is undefined: not folded
        assert_eq!(e(OP_SHIFT_LEFT_LOGICAL, &[4, 5]), None);
        assert_eq!(e(OP_IADD, &[3, 9]), None);
    }
}
