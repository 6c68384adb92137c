//! Several chains of batches made at once, their batches merged: each round, the next batch
//! of every chain still running goes out as one.
//!
//! `calibrate` fits the zones whole on K marker lattices (`calibrate`'s docs, "Lattice").
//! The K fits do not depend on one another, but each is a chain of batches of runs, each
//! batch waiting on the one before. Made one after another, a batch holds one fit's runs
//! (at most 16 on the demo's three zones), and on a runner with more workers than that the
//! rest wait. Made in lockstep, the fits' n-th batches go out together: K times the runs
//! in a K-th of the batches, so a cluster of K × 16 workers makes the K fits in the time
//! of one.
//!
//! Each chain runs on its own thread and [`asks`](Lockstep::ask) for its batches. A round
//! is made once every chain still running has asked (by the last to ask, or by the last
//! to [`finish`](Lockstep::finish) when the others are all waiting), its batches in the
//! order of the chains, so which items go together does not depend on timing. Where an
//! item's result depends on the item alone (an engine run on its trial), each chain gets
//! what it would have got alone, bit for bit.

use std::collections::BTreeMap;
use std::panic::AssertUnwindSafe;
use std::sync::{Condvar, Mutex, MutexGuard};

/// A batch runner shared by chains made in lockstep: items `T`, results `R`, errors `E`.
pub struct Lockstep<'a, T, R, E> {
    run: &'a (dyn Fn(Vec<T>) -> Result<Vec<R>, E> + Sync),
    round: Mutex<Round<T, R, E>>,
    answered: Condvar,
}

/// The round being gathered.
struct Round<T, R, E> {
    /// Chains that have not finished.
    running: usize,
    /// The batches asked for this round, by chain.
    asked: BTreeMap<usize, Vec<T>>,
    /// Each chain's share of the last round's results (None: the round failed).
    answers: BTreeMap<usize, Option<Vec<R>>>,
    /// The first failed round's error.
    error: Option<E>,
}

impl<'a, T, R, E> Lockstep<'a, T, R, E> {
    /// `chains` chains (numbered from 0) sharing `run`, which makes one batch and returns
    /// its items' results in order.
    pub fn new(run: &'a (dyn Fn(Vec<T>) -> Result<Vec<R>, E> + Sync), chains: usize) -> Self {
        Lockstep {
            run,
            round: Mutex::new(Round {
                running: chains,
                asked: BTreeMap::new(),
                answers: BTreeMap::new(),
                error: None,
            }),
            answered: Condvar::new(),
        }
    }

    /// Chain `chain`'s next batch, made with the other running chains' batches of the round;
    /// blocks until the round is made. None when the round failed (its error is kept for
    /// [`error`](Self::error)).
    pub fn ask(&self, chain: usize, items: Vec<T>) -> Option<Vec<R>> {
        let mut r = self.lock();
        r.asked.insert(chain, items);
        self.make_if_complete(&mut r);
        loop {
            if let Some(answer) = r.answers.remove(&chain) {
                return answer;
            }
            r = self.answered.wait(r).unwrap_or_else(|e| e.into_inner());
        }
    }

    /// A chain asks no more (done, failed or panicked): the round the others wait on may now
    /// be complete.
    pub fn finish(&self) {
        let mut r = self.lock();
        r.running -= 1;
        self.make_if_complete(&mut r);
    }

    /// The error of the first round that failed, if one did.
    pub fn error(&self) -> Option<E> {
        self.lock().error.take()
    }

    fn lock(&self) -> MutexGuard<'_, Round<T, R, E>> {
        // The lock is held only to gather or make a round; a chain that panicked holding
        // it left none half made, and its own thread's panic is what the caller sees.
        self.round.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Makes the round when every running chain has asked: its batches as one, in the
    /// order of the chains, each chain's results set aside for it.
    fn make_if_complete(&self, r: &mut Round<T, R, E>) {
        if r.asked.is_empty() || r.asked.len() < r.running {
            return;
        }
        let asked = std::mem::take(&mut r.asked);
        let sizes: Vec<(usize, usize)> = asked.iter().map(|(&c, b)| (c, b.len())).collect();
        // A runner that panics fails the round for every chain in it (none is left waiting)
        // and the panic goes on up this chain's thread.
        let items = asked.into_values().flatten().collect();
        let made = std::panic::catch_unwind(AssertUnwindSafe(|| (self.run)(items)));
        let mut panic = None;
        match made {
            Ok(Ok(results)) => {
                let mut results = results.into_iter();
                for &(chain, n) in &sizes {
                    r.answers
                        .insert(chain, Some(results.by_ref().take(n).collect()));
                }
            }
            Ok(Err(e)) => {
                r.error.get_or_insert(e);
            }
            Err(p) => panic = Some(p),
        }
        for (chain, _) in sizes {
            r.answers.entry(chain).or_insert(None);
        }
        self.answered.notify_all();
        if let Some(p) = panic {
            std::panic::resume_unwind(p);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What each chain got back (None: a round failed), the batches the runner was given,
    /// and the error kept.
    type Outcome = (Vec<Option<Vec<f64>>>, Vec<Vec<f64>>, Option<String>);

    /// Chain k of `n` asks k + 1 batches of k + 1 items, labelled 100 k + 10 batch + item,
    /// of a runner that records each batch, answers each item with its label + 0.5 and
    /// fails the batch that holds `fail`.
    fn chains(n: usize, fail: f64) -> Outcome {
        let batches = Mutex::new(Vec::new());
        let run = |items: Vec<f64>| {
            batches.lock().unwrap().push(items.clone());
            if items.contains(&fail) {
                return Err("the runner failed".to_string());
            }
            Ok(items.iter().map(|l| l + 0.5).collect())
        };
        let group = Lockstep::new(&run, n);
        let got = std::thread::scope(|s| {
            let threads: Vec<_> = (0..n)
                .map(|k| {
                    let group = &group;
                    s.spawn(move || {
                        let mut got = Vec::new();
                        for b in 0..=k {
                            let items = (0..=k).map(|i| (100 * k + 10 * b + i) as f64);
                            let Some(r) = group.ask(k, items.collect()) else {
                                group.finish();
                                return None;
                            };
                            got.extend(r);
                        }
                        group.finish();
                        Some(got)
                    })
                })
                .collect();
            threads.into_iter().map(|t| t.join().unwrap()).collect()
        });
        let error = group.error();
        (got, batches.into_inner().unwrap(), error)
    }

    /// Each round holds the next batch of every chain still running, in the order of the
    /// chains, and each chain gets its own items' results back, in its order.
    #[test]
    fn a_round_holds_every_running_chains_batch_and_each_gets_its_own_back() {
        let (got, batches, error) = chains(3, -1.0);
        assert_eq!(error, None);
        assert_eq!(
            batches,
            vec![
                vec![0.0, 100.0, 101.0, 200.0, 201.0, 202.0],
                vec![110.0, 111.0, 210.0, 211.0, 212.0],
                vec![220.0, 221.0, 222.0],
            ]
        );
        assert_eq!(got[0], Some(vec![0.5]));
        assert_eq!(got[1], Some(vec![100.5, 101.5, 110.5, 111.5]));
        let third: Vec<f64> = [200, 201, 202, 210, 211, 212, 220, 221, 222]
            .iter()
            .map(|&l| l as f64 + 0.5)
            .collect();
        assert_eq!(got[2], Some(third));
    }

    /// A failed round fails every chain in it and keeps the runner's error; the chains
    /// that finished before it are not touched.
    #[test]
    fn a_failed_round_fails_each_chain_in_it_and_keeps_the_runners_error() {
        let (got, batches, error) = chains(3, 110.0);
        assert_eq!(error.as_deref(), Some("the runner failed"));
        assert_eq!(got, vec![Some(vec![0.5]), None, None]);
        assert_eq!(batches.len(), 2);
    }

    /// A runner that panics fails the round for every chain in it, so none waits for
    /// ever, and the panic reaches the thread that made the round.
    #[test]
    fn a_panicking_runner_leaves_no_chain_waiting() {
        let run = |_: Vec<u8>| -> Result<Vec<u8>, ()> { panic!("the runner panicked") };
        let group = Lockstep::new(&run, 2);
        let joined: Vec<std::thread::Result<Option<Vec<u8>>>> = std::thread::scope(|s| {
            let threads: Vec<_> = (0..2)
                .map(|k| {
                    let group = &group;
                    s.spawn(move || {
                        let got = group.ask(k, vec![k as u8]);
                        group.finish();
                        got
                    })
                })
                .collect();
            threads.into_iter().map(|t| t.join()).collect()
        });
        let panicked = joined.iter().filter(|j| j.is_err()).count();
        let failed = joined.iter().filter(|j| matches!(j, Ok(None))).count();
        assert_eq!((panicked, failed), (1, 1));
    }
}
