//! Passes 1 and 2 of a segment, which need nothing of the targets before it but the nominal
//! directions they leave: (1) the signs and directions of the nominal motion on arrival at
//! every target; (2) every target solved with each axis's gear engaged on the flank of its
//! nominal direction (after any motion longer than the play that is where it is), in chains
//! of warm starts cut at fixed places in execution order so that a program compensated whole
//! or window by window solves every target alike, the chains on rayon's pool; then the nominal
//! TCP of every command placed, in parallel too. Also where a pass runs its independent pieces
//! ([`Executor`]: the pool or the calling thread).

use super::solving::{solve_target, tcp_error};
use super::timeline::Timeline;
use super::{Command, Ctx, Options, Outcome, Target, REST_DEG};
use crate::compensate::solve::{self, Method};
use crate::model::{AxisHistory, Direction, Model};
use crate::motion::frame::Frame;
use crate::motion::nominal::{Arm, Nominal};
use std::mem::MaybeUninit;

/// Targets per chunk of the parallel pass that places the first-pass commands.
pub(super) const PLACE_CHUNK: usize = 1024;

/// The signs of an arrival motion ([`signs`]); `None` when it comes from an unknown place.
pub(super) type Signs = Option<[i8; 6]>;

/// What the direction logic uses of an arrival motion: per axis −1, +1, or 0 at rest.
pub(super) fn signs(v: Option<[f64; 6]>) -> Signs {
    v.map(|v| {
        v.map(|x| {
            if x.abs() < REST_DEG {
                0
            } else if x > 0.0 {
                1
            } else {
                -1
            }
        })
    })
}

/// The direction state after arriving with motion of `v`'s signs from state `before`.
pub(super) fn arrive_signs(before: &[Direction; 6], v: Signs) -> [Direction; 6] {
    match v {
        None => [Direction::Unknown; 6],
        Some(v) => std::array::from_fn(|i| match v[i] {
            0 => before[i],
            x => Direction::from_sign(x as i32),
        }),
    }
}

/// Directions of the nominal motion at every target, from the directions before the first.
#[cfg(any(test, feature = "internals"))]
pub fn nominal_directions(targets: &[Target], start: [Direction; 6]) -> Vec<[Direction; 6]> {
    let signs: Vec<Signs> = targets.iter().map(|t| signs(t.arrival)).collect();
    directions_after(&signs, start)
}

/// The direction states after arriving with motions of `signs` one after another.
pub(super) fn directions_after(signs: &[Signs], start: [Direction; 6]) -> Vec<[Direction; 6]> {
    let mut state = start;
    signs
        .iter()
        .map(|&v| {
            state = arrive_signs(&state, v);
            state
        })
        .collect()
}

/// Passes 1 and 2 of a segment: what needs nothing of the targets before it but the nominal
/// directions they leave (`nominal_start`), so it may run while the segment before is still
/// being settled ([`settle`]).
pub struct FirstPasses {
    /// The targets' outcomes, with room in front for the history's.
    pub(super) outcomes: Timeline,
    pub(super) nominal_signs: Vec<Signs>,
    /// The unrounded TCP of every first-pass command, and its pose in the base frame before
    /// the choice of Euler triple (see [`Command::unchosen`]); [`settle`] completes them in
    /// place.
    pub(super) commands: Vec<Command>,
}

impl FirstPasses {
    /// The nominal directions after the segment (the next segment's `nominal_start`).
    pub fn nominal_end(&self) -> Option<[Direction; 6]> {
        self.outcomes.targets().last().map(|o| o.nominal_directions)
    }
}

/// Where a pass runs its independent pieces: on rayon's pool or in order on the calling
/// thread ([`Options::parallel`]), chosen once per pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Executor {
    Pool,
    Inline,
}

impl Executor {
    pub(super) fn of(options: &Options) -> Executor {
        if options.parallel {
            Executor::Pool
        } else {
            Executor::Inline
        }
    }

    /// Runs `a` and `b`, beside each other on the pool.
    pub(super) fn join<A: Send, B: Send>(
        self,
        a: impl FnOnce() -> A + Send,
        b: impl FnOnce() -> B + Send,
    ) -> (A, B) {
        match self {
            Executor::Pool => rayon::join(a, b),
            Executor::Inline => (a(), b()),
        }
    }

    /// `work` of every chunk of `items` (with the chunk's index), in order.
    pub(super) fn map_chunks<T: Send, R: Send>(
        self,
        items: &mut [T],
        chunk: usize,
        work: impl Fn(usize, &mut [T]) -> R + Sync + Send,
    ) -> Vec<R> {
        use rayon::prelude::*;
        match self {
            Executor::Pool => items
                .par_chunks_mut(chunk)
                .enumerate()
                .map(|(c, a)| work(c, a))
                .collect(),
            Executor::Inline => items
                .chunks_mut(chunk)
                .enumerate()
                .map(|(c, a)| work(c, a))
                .collect(),
        }
    }
}

/// Targets in a chain of warm starts ([`solve::Chain`]); each chain's first is solved afresh.
/// Chains are cut at every multiple of this in execution order: fixed places, so that a
/// program compensated whole or window by window solves every target alike, and chains of
/// a window are worked in parallel.
pub(super) const CHAIN: usize = 256;

/// Where a segment's targets stand among the chains: how many targets came before them in
/// execution order, and the chain the first of them continues.
#[derive(Clone, Copy, Debug, Default)]
pub struct Chains {
    pub(super) ordinal: u64,
    pub(super) open: solve::Chain,
}

/// Passes 1 and 2 of `targets`, the nominal directions before the first given, `chains`
/// where the targets before them left the warm starts (moved on past them).
pub fn first_passes(
    model: &Model,
    tools: &[Frame],
    targets: &[Target],
    nominal_start: [Direction; 6],
    chains: &mut Chains,
    options: &Options,
) -> FirstPasses {
    let run = Executor::of(options);
    // Pass 1: the nominal motions' signs (the re-check needs them again), their directions.
    let nominal_signs: Vec<Signs> = targets.iter().map(|t| signs(t.arrival)).collect();
    let nominal = directions_after(&nominal_signs, nominal_start);
    // Pass 2: every target solved with the plays engaged on the nominal flanks.
    let ctx = Ctx::new(model, tools, &[], targets, options.method);
    let outcomes = Timeline::solved(targets.len(), |slots| {
        solve_chains(&ctx, &nominal, chains, run, slots)
    });
    let commands = place_commands(&ctx, outcomes.targets(), run);
    FirstPasses {
        outcomes,
        nominal_signs,
        commands,
    }
}

/// Solves `targets` (outcomes into `slots`, every one written) in their chains of warm
/// starts, each worked in order, the first continuing the open one of `chains`, which then
/// moves on past them.
pub(super) fn solve_chains(
    ctx: &Ctx,
    nominal: &[[Direction; 6]],
    chains: &mut Chains,
    run: Executor,
    slots: &mut [MaybeUninit<Outcome>],
) {
    let n = slots.len();
    let head = ((CHAIN - (chains.ordinal % CHAIN as u64) as usize) % CHAIN).min(n);
    let (head_slots, rest) = slots.split_at_mut(head);
    type Slots<'s> = &'s mut [MaybeUninit<Outcome>];
    let work = |from: usize, slots: Slots, chain: solve::Chain| -> solve::Chain {
        let mut along = solve::Along::new(ctx.model, chain);
        for (k, slot) in slots.iter_mut().enumerate() {
            let i = from + k;
            let engaged = nominal[i].map(AxisHistory::engaged);
            let target = &ctx.targets[i];
            let chain = Some(&mut along);
            first_pass(
                ctx.model, ctx.tools, target, &engaged, ctx.method, chain, slot,
            );
        }
        along.chain
    };
    // The chain continued from the segment before runs beside the fresh ones.
    let continued = chains.open;
    let (open, ends) = run.join(
        || work(0, head_slots, continued),
        || {
            run.map_chunks(rest, CHAIN, |p, slots| {
                work(head + p * CHAIN, slots, solve::Chain::default())
            })
        },
    );
    chains.open = ends.last().copied().unwrap_or(open);
    chains.ordinal += n as u64;
}

/// Where the nominal robot places every first-pass command (the rewrite's numbers): its TCP,
/// and for a Cartesian target its pose before the choice of Euler triple.
pub(super) fn place_commands(ctx: &Ctx, solved: &[Outcome], run: Executor) -> Vec<Command> {
    let blank = Command {
        tcp: Frame::identity(),
        correction: (0.0, 0.0),
        unchosen: None,
    };
    let mut commands: Vec<Command> = vec![blank; solved.len()];
    let arm = Nominal(&ctx.model.robot);
    run.map_chunks(&mut commands, PLACE_CHUNK, |c, placings| {
        for (j, placing) in placings.iter_mut().enumerate() {
            let k = c * PLACE_CHUNK + j;
            let axes = &solved[k].axes_deg;
            placing.tcp = arm.tcp(axes, ctx.tool(k));
            placing.unchosen = ctx.unchosen(k, &placing.tcp);
        }
    });
    commands
}

pub(super) fn first_pass(
    model: &Model,
    tools: &[Frame],
    target: &Target,
    histories: &[AxisHistory; 6],
    method: Method,
    mut chain: Option<&mut solve::Along>,
    out: &mut MaybeUninit<Outcome>,
) {
    let directions = histories.map(|h| h.simple_direction());
    // Written first, whatever follows (`Timeline::solved` relies on it).
    let out = out.write(Outcome::unsolved(*target.nominal_axes, directions));
    let tool = &tools[target.tool as usize];
    if let Some(c) = chain.as_deref_mut() {
        c.chain.follow_tool(target.tool);
    }
    if !target.compensate {
        if let Some(c) = chain {
            c.chain.forget();
        }
        out.before = tcp_error(model, tool, &target.nominal_axes, histories, &target.goal);
        out.residual = out.before;
        return;
    }
    let solved = solve_target(
        model,
        tool,
        target,
        histories,
        *target.nominal_axes,
        [false; 6],
        method,
        chain.as_deref_mut(),
    );
    if let Some(c) = chain.map(|c| &mut c.chain) {
        match &solved {
            Ok((sol, held)) if !held.contains(&true) => c.record(
                std::array::from_fn(|i| sol.axes_deg[i] - target.nominal_axes[i]),
                sol.initial,
                sol.residual,
            ),
            _ => c.forget(),
        }
    }
    match solved {
        Ok((sol, turn_held)) => {
            out.changed = sol.axes_deg != target.nominal_axes;
            out.axes_deg = sol.axes_deg.into();
            out.residual = sol.residual;
            out.iterations = sol.iterations;
            out.turn_held = turn_held;
            // The error at the nominal command (the start, unless a turn was kept by holding).
            out.before = if turn_held.iter().any(|&h| h) {
                tcp_error(model, tool, &target.nominal_axes, histories, &target.goal)
            } else {
                sol.initial
            };
        }
        Err(e) => {
            out.error = Some(e);
            out.before = tcp_error(model, tool, &target.nominal_axes, histories, &target.goal);
            out.residual = out.before;
        }
    }
}
