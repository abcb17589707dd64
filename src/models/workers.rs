//! Independent per-mesh work (registration of every training mesh) spread over the cores.
//!
//! Workers take the next item from a shared counter; results come back by index, so the
//! output does not depend on the number of cores or on which core finished first. The calling
//! thread keeps the progress reporting (and with it cancellation): it receives every finished
//! item and may stop the workers between items.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc;

/// Cores to use for `items` independent items.
fn worker_count(items: usize) -> usize {
    std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(items)
        .max(1)
}

/// `f(item)` for every item, in item order, computed on up to the available cores.
///
/// `finished(done)` runs on the calling thread each time an item finishes (`done` items so
/// far); an error from it stops the workers after their current item and is returned, as is
/// the first error of `f` (by item order among those computed).
pub fn map_items<T, R, E, F, P>(items: &[T], f: F, mut finished: P) -> Result<Vec<R>, E>
where
    T: Sync,
    R: Send,
    E: Send,
    F: Fn(&T) -> Result<R, E> + Sync,
    P: FnMut(usize) -> Result<(), E>,
{
    let workers = worker_count(items.len());
    if workers <= 1 {
        let mut out = Vec::with_capacity(items.len());
        for (k, item) in items.iter().enumerate() {
            out.push(f(item)?);
            finished(k + 1)?;
        }
        return Ok(out);
    }
    let next = AtomicUsize::new(0);
    let stop = AtomicBool::new(false);
    let mut slots: Vec<Option<Result<R, E>>> = items.iter().map(|_| None).collect();
    let mut stopped: Option<E> = None;
    std::thread::scope(|scope| {
        let (sender, receiver) = mpsc::channel::<(usize, Result<R, E>)>();
        for _ in 0..workers {
            let sender = sender.clone();
            let (next, stop, f) = (&next, &stop, &f);
            scope.spawn(move || {
                while !stop.load(Ordering::Relaxed) {
                    let k = next.fetch_add(1, Ordering::Relaxed);
                    let Some(item) = items.get(k) else { break };
                    let result = f(item);
                    let failed = result.is_err();
                    if sender.send((k, result)).is_err() || failed {
                        stop.store(true, Ordering::Relaxed);
                        break;
                    }
                }
            });
        }
        drop(sender);
        let mut done = 0;
        for (k, result) in receiver {
            slots[k] = Some(result);
            done += 1;
            if stopped.is_none()
                && let Err(e) = finished(done)
            {
                stop.store(true, Ordering::Relaxed);
                stopped = Some(e);
            }
        }
    });
    if let Some(e) = stopped {
        return Err(e);
    }
    let mut out = Vec::with_capacity(items.len());
    for slot in slots {
        match slot {
            Some(result) => out.push(result?),
            // Only reachable after a worker stopped on an error of an earlier item.
            None => continue,
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn results_come_back_in_item_order_with_every_item_reported() {
        let items: Vec<u64> = (0..50).collect();
        let mut reported = Vec::new();
        let out: Result<Vec<u64>, String> = map_items(
            &items,
            |&x| Ok(x * x),
            |done| {
                reported.push(done);
                Ok(())
            },
        );
        assert_eq!(
            out.unwrap(),
            items.iter().map(|x| x * x).collect::<Vec<_>>()
        );
        assert_eq!(reported, (1..=50).collect::<Vec<_>>());
    }

    #[test]
    fn an_item_error_is_returned() {
        let items: Vec<u64> = (0..20).collect();
        let out: Result<Vec<u64>, String> = map_items(
            &items,
            |&x| {
                if x == 7 {
                    Err(format!("item {x}"))
                } else {
                    Ok(x)
                }
            },
            |_| Ok(()),
        );
        assert_eq!(out.unwrap_err(), "item 7");
    }

    #[test]
    fn an_error_from_the_report_stops_the_work() {
        let items: Vec<u64> = (0..200).collect();
        let computed = AtomicUsize::new(0);
        let out: Result<Vec<u64>, String> = map_items(
            &items,
            |&x| {
                computed.fetch_add(1, Ordering::Relaxed);
                std::thread::sleep(std::time::Duration::from_millis(2));
                Ok(x)
            },
            |done| {
                if done >= 3 {
                    Err("cancelled".into())
                } else {
                    Ok(())
                }
            },
        );
        assert_eq!(out.unwrap_err(), "cancelled");
        assert!(computed.load(Ordering::Relaxed) < 200);
    }
}
