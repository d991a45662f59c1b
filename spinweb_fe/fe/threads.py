"""How a threaded run splits its work (the ranges the thread kernels of fe.step take)."""

from __future__ import annotations

import numpy as np

from spinweb_fe.fe.step import split


def thread_ranges(elem_nodes: np.ndarray, n_nodes: int, threads: int, grouped: bool,
                  anywhere0: bool = False):
    """(ebounds, nbounds, lists) of a run on ``threads`` threads.

    ebounds: the contiguous element chunks (:func:`split`; the strength pass takes them);
    lists: None, or (grouped=True) the element list (every element once, grouped by the node
    block of its first node, in element order within a block) and its chunk bounds, so that
    thread c's elements touch the nodes of block c and a few beyond; nbounds (3, threads + 1):
    the node blocks, and for each chunk of the pass in use the first and one past the last
    node its elements touch (:func:`integrate_threads` folds only there; buffer 0 everywhere
    with ``anywhere0``: the bundles gather their forces into it)."""
    ebounds = split(elem_nodes.shape[0], threads)
    nbounds = np.zeros((3, threads + 1), np.int64)
    nbounds[0] = split(n_nodes, threads)
    lists = None
    elist = np.arange(elem_nodes.shape[0], dtype=np.int64)
    cuts = ebounds
    if grouped:
        block = np.searchsorted(nbounds[0], elem_nodes[:, 0], side="right") - 1
        elist = np.argsort(block, kind="stable").astype(np.int64)
        cuts = np.searchsorted(block[elist], np.arange(threads + 1)).astype(np.int64)
        lists = (cuts, elist)
    for c in range(threads):
        chunk = elem_nodes[elist[cuts[c]:cuts[c + 1]]]
        if len(chunk):
            nbounds[1, c], nbounds[2, c] = chunk.min(), chunk.max() + 1
    if anywhere0:
        nbounds[1, 0], nbounds[2, 0] = 0, n_nodes
    return ebounds, nbounds, lists
