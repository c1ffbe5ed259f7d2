"""The solve on a Ray cluster (https://docs.ray.io): each phase's gather split over workers.

Every phase of the solve (the direct light, each bounce, the final gather, and the error
estimate's two passes) is a gather each receiving surface does on its own from the previous
step's coefficients of all receivers (bsgi.SolveSteps). Here the driver keeps the bookkeeping
between phases (the sums, when to stop, the extrapolated tail, the estimate's sums) and sends
each phase's gather out in groups of receivers to Ray actors.
Each actor holds the scene, its BVH and its receivers once (rebuilt from the pickled scene) and
gets the previous step's coefficients from Ray's object store, put there once per phase. The
result equals the local solve's: the same code gathers the same nodes.

Ray is optional: it is imported when a RayExecutor first solves.
"""
from __future__ import annotations

import threading
import time
from collections import deque
from typing import Any, Callable, Optional

import numpy as np

from . import _core
from .rebuildable import settings_fields, settings_from


def import_ray() -> Any:
    try:
        import ray
    except ImportError as error:
        raise ImportError("the distributed solve needs Ray: pip install ray (into the Python that runs bsgi)") from error
    return ray


def sides_of_parts(surfaces: int, parts: int, each_part: Callable[[str, Optional[np.ndarray]], list]) -> list:
    """The sides probe's answer from its parts (_core.SidesProbe), as SolveWorker runs them:
    each_part(method, lit) returns SolveWorker.method(part, parts, lit) of every part, in part
    order. First each part's cells lit directly; then every part settles its cells given the
    cells lit in any part (packed bits), until none lights more; then each part's sides."""
    lit = np.zeros(2 * 36 * surfaces, bool)  # cells: (surface * 2 + side) * 36 + cell
    for cells in each_part("probe", None):
        lit[cells] = True
    while True:
        before = int(np.count_nonzero(lit))
        for cells in each_part("probe", np.packbits(lit)):
            lit[cells] = True
        if int(np.count_nonzero(lit)) == before:
            break
    parts_sides = each_part("probed_sides", np.packbits(lit))
    return [parts_sides[_core.SidesProbe.owner(i, parts, surfaces)][i] for i in range(surfaces)]


class SolveWorker:
    """A Ray actor's state: the scene, its parts of the sides probe while they run, and its
    SolveSteps once the sides are known, each built when first needed (and again if Ray restarts
    the actor: every call carries what rebuilding needs)."""

    def __init__(self, scene: _core.Scene, fields: dict) -> None:
        self.scene = scene
        self.settings = settings_from(fields)
        self.probes: dict = {}  # part -> _core.SidesProbe
        self.steps: Optional[_core.SolveSteps] = None
        self.lock = threading.Lock()  # Ray's second actor thread (cancel) may call in meanwhile
        self.progress = _core.Progress()
        self.unpacked = -1  # the phase (the driver's count) whose input the splines hold

    def probe(self, part: int, parts: int, lit: Optional[np.ndarray]) -> np.ndarray:
        """The cells of the sides probe's part `part` lit since this actor last answered for it
        (all of them if it built the part here only now): with `lit` None, those lit directly;
        else after settling given `lit`, the packed bits of the cells lit in any part."""
        with self.lock:
            probe = self.probes.get(part)
            if probe is None:
                probe = self.probes[part] = _core.SidesProbe(self.scene, self.settings, part, parts)
            if lit is None:
                return probe.lit_directly()
            return probe.settle(np.flatnonzero(np.unpackbits(lit)).astype(np.uint32))

    def probed_sides(self, part: int, parts: int, lit: np.ndarray) -> list:
        """The sides of the surfaces of part `part`, once no part lights more (`lit`: the cells
        lit, packed bits); frees the part."""
        self.probe(part, parts, lit)  # rebuilds it if Ray restarted this actor since
        with self.lock:
            return self.probes.pop(part).sides()

    def solve_steps(self, sides: list) -> _core.SolveSteps:
        """The SolveSteps of the scene with these sides (built at the first call)."""
        with self.lock:
            if self.steps is None:
                self.steps = _core.SolveSteps(self.scene, self.settings, _core.Progress(), sides)
            return self.steps

    def prepare(self, sides_box: list) -> None:
        """Builds the SolveSteps (places the knots) while the driver does its own."""
        self.solve_steps(import_ray().get(sides_box[0]))

    def gather(self, phase: str, begin: int, end: int, coefficients: np.ndarray, nodes: int, settled: list,
               phase_index: int, sides_box: list) -> tuple:
        """(the group's coefficients, its rays, the seconds it took here). A phase's later groups
        here read its input from the splines the first one unpacked it into. `sides_box`: [the
        sides' object ref], read only if this actor has no SolveSteps (restarted by Ray)."""
        progress = _core.Progress()
        progress.begin_stage(phase, 0, 1, nodes)
        self.progress = progress  # what cancel() sees, from Ray's second actor thread
        steps = self.steps if self.steps is not None else self.solve_steps(import_ray().get(sides_box[0]))
        start = time.perf_counter()
        part, rays = steps.gather(phase, begin, end, coefficients, progress, settled,
                                  unpacked=self.unpacked == phase_index)
        self.unpacked = phase_index
        return part, rays, time.perf_counter() - start

    def cancel(self) -> None:
        """Stops the running gather (it raises SolveCancelled)."""
        self.progress.cancel()

    def cpu_seconds(self) -> float:
        """CPU time of this worker's process so far (set-up and gathers, all threads)."""
        return time.process_time()


def receiver_groups(nodes: list, count: int, cost_per_node=None) -> list:
    """Consecutive receivers in at most `count` groups of about equal cost (nodes times
    `cost_per_node`, 1 if None): (begin, end, nodes) each. A group ends at the receiver whose
    cumulative cost is nearest its share of the total."""
    cost = np.asarray(nodes, float) * (1.0 if cost_per_node is None else np.asarray(cost_per_node, float))
    if len(cost) == 0:
        return []
    cumulative = np.cumsum(cost)
    ends = set()
    for g in range(1, count):
        target = cumulative[-1] * g / count
        k = int(np.searchsorted(cumulative, target))  # the first receiver that reaches it
        before = cumulative[k - 1] if k > 0 else 0.0
        ends.add(k + 1 if k < len(cost) and cumulative[k] - target <= target - before else k)
    bounds = [0, *sorted(e for e in ends if 0 < e < len(cost)), len(cost)]
    return [(b, e, int(sum(nodes[b:e]))) for b, e in zip(bounds, bounds[1:])]


def guided_groups(nodes: list, workers: int, cost_per_node=None, smallest: float = 1 / 32) -> list:
    """Consecutive receivers in groups of falling cost, the largest first (guided scheduling):
    each takes 1 / (2 workers) of the cost not yet grouped, and at least `smallest` of the
    whole, so a phase ends on small groups and no worker waits long for another's last one
    (equal groups left the workers 0.72-0.98 busy in a phase). (begin, end, nodes) each."""
    cost = np.asarray(nodes, float) * (1.0 if cost_per_node is None else np.asarray(cost_per_node, float))
    if len(cost) == 0:
        return []
    cumulative = np.cumsum(cost)
    total = float(cumulative[-1])
    if not total > 0:
        return [(0, len(cost), int(sum(nodes)))]
    # A phase whose cost lies mostly in its last receiver (a glossy one, or one whose measured
    # cost a busy machine inflated) would be one group, and the other workers idle: the first
    # group stops before the last receiver that costs anything.
    last = int(np.flatnonzero(cost)[-1])
    groups, begin, done = [], 0, 0.0
    while begin < len(cost):
        want = max((total - done) / (2 * workers), smallest * total)
        end = min(max(int(np.searchsorted(cumulative, done + want)) + 1, begin + 1), len(cost))
        if not groups and workers > 1 and last > 0 and end > last:
            end = last
        groups.append((begin, end, int(sum(nodes[begin:end]))))
        begin, done = end, float(cumulative[end - 1])
    return groups


class RayExecutor:
    """Runs bsgi.solve's phases on Ray actors.

    ``address``: the Ray cluster (``"auto"``: the one running here, started by ``ray start
    --head``; ``"ray://host:10001"``: a remote one; None: a running ray.init(), or else a local
    Ray of this machine's cores). ``workers``: actors (default: the cluster's CPUs /
    ``threads_per_worker``), each reserving ``threads_per_worker`` CPUs and gathering on as many
    threads. A phase is split into groups of falling cost (guided_groups), each handed to the
    next free worker; with form-factor rows, into ``groups_per_worker`` groups per worker, each
    kept by its worker (which keeps their rows). A worker lost mid-solve is restarted by Ray
    (``max_retries`` times) and its group gathered again; one lost for good (its machine gone)
    leaves its groups to the others.
    ``actors`` holds the workers of the running solve.
    """

    def __init__(self, address: Optional[str] = None, workers: Optional[int] = None, threads_per_worker: int = 1,
                 groups_per_worker: int = 4, max_retries: int = 3, poll_seconds: float = 0.05) -> None:
        if threads_per_worker < 1 or (workers is not None and workers < 1) or groups_per_worker < 1:
            raise ValueError("RayExecutor: workers, threads_per_worker and groups_per_worker must be >= 1")
        self.address = address
        self.workers = workers
        self.threads_per_worker = threads_per_worker
        self.groups_per_worker = groups_per_worker
        self.max_retries = max_retries
        self.poll_seconds = poll_seconds
        self.actors: list = []
        self.bytes_sent: list = []  # of each phase's coefficients put into the object store
        # Of each phase: (its name, when it began and ended on the driver's perf_counter, each
        # group's seconds on its worker); what the driver did alone lies between the phases.
        self.phase_times: list = []
        self.keep_groups = False  # each group stays on its worker (which keeps its form-factor rows)
        self.lost: set = set()  # workers gone for good (their groups went to the others)
        self.worker_cpu_seconds: list = []  # of each worker's process, at the end of the last solve
        self.receiver_nodes: list = []  # of each receiver of the bounces, as the direct light gathered them
        # Seconds a node of each receiver takes, as last measured on the workers (up to a factor
        # the same for all receivers in a phase): a glossy node costs many diffuse ones, so
        # groups of equal nodes would leave a worker idle while another gathers the glossy group.
        self.cost_per_node: Optional[np.ndarray] = None
        self.sides_box: list = []  # [the object ref of the running solve's sides]
        self.scene_ref = None  # of the running solve's scene
        self.probe_rounds = 0  # of the last sides probe: its rounds of settling, and the bytes of lit cells it sent
        self.probe_bytes = 0

    def connect(self) -> Any:
        ray = import_ray()
        if not ray.is_initialized():
            try:
                ray.init(address=self.address, log_to_driver=False)
            except (ConnectionError, RuntimeError, ValueError, SystemExit) as error:  # Ray exits when no cluster answers
                raise RuntimeError(f"cannot connect to the Ray cluster at '{self.address}' ({error!r})") from None
        return ray

    def start_workers(self, ray: Any, scene: _core.Scene, settings: _core.SolverSettings) -> None:
        """self.actors: the workers, each building the scene (from one pickled copy, kept in
        self.scene_ref while they run: Ray rebuilds a restarted actor from it)."""
        cpus = int(ray.cluster_resources().get("CPU", 0))
        count = self.workers or max(1, cpus // self.threads_per_worker)
        if count * self.threads_per_worker > cpus:  # the workers that do not fit would never start
            raise ValueError(f"RayExecutor: {count} workers of {self.threads_per_worker} threads need "
                             f"{count * self.threads_per_worker} CPUs; the Ray cluster has {cpus}")
        # A worker's CPUs are on one machine: one of more threads than any machine has would wait forever.
        largest = int(max((n["Resources"].get("CPU", 0) for n in ray.nodes() if n.get("Alive")), default=0))
        if self.threads_per_worker > largest:
            raise ValueError(f"RayExecutor: a worker of {self.threads_per_worker} threads needs a machine of as many "
                             f"CPUs; the largest in the Ray cluster has {largest}")
        fields = settings_fields(settings)
        fields["threads"] = self.threads_per_worker
        actor = ray.remote(num_cpus=self.threads_per_worker, max_restarts=self.max_retries,
                           max_task_retries=self.max_retries, max_concurrency=2)(SolveWorker)
        self.scene_ref = ray.put(scene)  # pickled once (bsgi.Scene keeps the calls that built it)
        self.actors = [actor.remote(self.scene_ref, fields) for _ in range(count)]
        self.lost = set()
        self.phase_times = []

    def stop_workers(self, ray: Any) -> None:
        for a in self.actors:
            ray.kill(a)  # also ends a gather still running after a cancel
        self.actors = []
        self.scene_ref = None

    def solve(self, scene: _core.Scene, settings: _core.SolverSettings, progress: _core.Progress,
              sides: Optional[list] = None) -> _core.Solution:
        ray = self.connect()
        self.start_workers(ray, scene, settings)
        self.bytes_sent = []
        self.keep_groups = settings.form_factors
        self.cost_per_node = None
        try:
            # The workers probe the sides (unless given them), then take them and place the same
            # knots as the driver, each on its own.
            if sides is None:
                sides = self.probe_parts(ray, progress, len(scene))
            self.sides_box = [ray.put(sides)]  # in a list: Ray passes the ref, read by a restarted worker
            for a in self.live_actors():
                a.prepare.remote(self.sides_box)
            steps = _core.SolveSteps(scene, settings, progress, sides)
            solution = steps.solve(progress, lambda *args: self.run_phase(ray, progress, *args))
            alive = [a for w, a in enumerate(self.actors) if w not in self.lost]
            self.worker_cpu_seconds = ray.get([a.cpu_seconds.remote() for a in alive])
            return solution
        finally:
            self.stop_workers(ray)

    def live_actors(self) -> list:
        return [a for w, a in enumerate(self.actors) if w not in self.lost]

    def probe_sides(self, scene: _core.Scene, settings: _core.SolverSettings, progress: _core.Progress) -> list:
        """The sides probe (bsgi.probe_sides) split over this executor's workers, started for it."""
        ray = self.connect()
        self.start_workers(ray, scene, settings)
        try:
            return self.probe_parts(ray, progress, len(scene))
        finally:
            self.stop_workers(ray)

    def probe_parts(self, ray: Any, progress: _core.Progress, surfaces: int) -> list:
        """The sides probe in parts, one a worker (_core.SidesProbe): each probes its part's
        cells, then all settle their cells given the cells any part lit, exchanged as bits, until
        none lights more (the one probe's answer: lighting only grows). A part whose worker is
        lost for good goes to another, which probes it afresh."""
        parts = len(self.live_actors())
        holder = dict(enumerate(w for w in range(len(self.actors)) if w not in self.lost))  # part -> worker

        seconds = []  # of each part's call in each round, from the round's start to its answer
        began = time.perf_counter()
        self.probe_rounds, self.probe_bytes = 0, 0

        def each_part(method: str, lit: Optional[np.ndarray]) -> list:
            """method(part, parts, lit) on each part's worker, cancellable; the results in part order."""
            if lit is not None:
                self.probe_rounds += method == "probe"
                self.probe_bytes += lit.nbytes
            args = (None if lit is None else ray.put(lit),)  # once per round, fetched once per machine
            start = time.perf_counter()
            running = {getattr(self.actors[holder[p]], method).remote(p, parts, *args): p for p in range(parts)}
            results: dict = {}
            while running:
                if progress.cancelled:
                    raise _core.SolveCancelled("solve cancelled")
                ready, _ = ray.wait(list(running), num_returns=1, timeout=self.poll_seconds)
                for ref in ready:
                    p = running.pop(ref)
                    try:
                        results[p] = ray.get(ref)
                        seconds.append(time.perf_counter() - start)
                    except ray.exceptions.RayActorError:
                        self.lost.add(holder[p])
                        alive = [w for w in range(len(self.actors)) if w not in self.lost]
                        if not alive:
                            raise RuntimeError("the distributed solve lost all its Ray workers") from None
                        holder[p] = alive[p % len(alive)]
                        running[getattr(self.actors[holder[p]], method).remote(p, parts, *args)] = p
            return [results[p] for p in range(parts)]

        progress.begin_stage("probing sides", 0, 1, 1)
        sides = sides_of_parts(surfaces, parts, each_part)
        self.phase_times.append(("probing sides", began, time.perf_counter(), seconds))
        return sides

    def run_phase(self, ray: Any, progress: _core.Progress, phase: str, coefficients: np.ndarray, nodes: list) -> tuple:
        """One phase's gather for all receivers, group by group on the free workers."""
        began = time.perf_counter()
        coefficients_ref = ray.put(coefficients)  # once per phase, fetched once per machine
        self.bytes_sent.append(coefficients.nbytes)
        # With form-factor rows, group g goes to worker g mod n, the same every phase: a worker
        # casts the rows of its groups once, and takes no other's. Otherwise each free worker
        # takes the next group of one queue.
        alive = [w for w in range(len(self.actors)) if w not in self.lost]
        # A receiver of 0 nodes has settled (SolverSettings.settle_factor): it does not gather.
        if phase == "direct":
            self.receiver_nodes = nodes  # before any receiver settles
        if self.cost_per_node is None or len(self.cost_per_node) != len(nodes):
            self.cost_per_node = np.ones(len(nodes))
        if self.keep_groups:
            # With form-factor rows the groups are the same every phase, each on its worker's
            # queue, and so split by the receivers' own nodes.
            own = self.receiver_nodes if phase in ("bounce", "late bounce") else nodes
            groups = receiver_groups(own, len(alive) * self.groups_per_worker)
        else:
            # Otherwise the groups' costs fall as measured in the phases before (the receivers'
            # relative costs hold from phase to phase: the final gather's nodes are finer, its
            # glossy ones as much dearer), all in one queue, the largest first.
            groups = guided_groups(nodes, len(alive), self.cost_per_node)
        queues = {w: deque() for w in alive}
        shared: deque = deque()
        for g, (begin, end, _) in enumerate(groups):
            group = (begin, end, sum(nodes[begin:end]), [k for k in range(begin, end) if nodes[k] == 0])
            (queues[alive[g % len(alive)]] if self.keep_groups else shared).append(group)
        idle = list(alive)
        running: dict = {}
        parts: dict = {}
        rays = 0
        measured = []  # (begin, end, seconds) of each group
        while shared or any(queues.values()) or running:
            if progress.cancelled:
                for w, _ in running.values():
                    self.actors[w].cancel.remote()
                raise _core.SolveCancelled("solve cancelled")
            if not queues:
                raise RuntimeError("the distributed solve lost all its Ray workers")
            for w in list(idle):
                queue = queues[w] if self.keep_groups else shared
                if queue:
                    idle.remove(w)
                    group = queue.popleft()
                    ref = self.actors[w].gather.remote(phase, *group[:2], coefficients_ref, *group[2:], len(self.bytes_sent),
                                                       self.sides_box)
                    running[ref] = (w, group)
            ready, _ = ray.wait(list(running), num_returns=1, timeout=self.poll_seconds)
            for ref in ready:
                w, group = running.pop(ref)
                try:
                    part, group_rays, seconds = ray.get(ref)
                except ray.exceptions.RayActorError:
                    # Gone beyond Ray's restarts (its machine left the cluster): its groups go to the others.
                    self.lost.add(w)
                    left = [group, *queues.pop(w)]
                    if not queues:
                        raise RuntimeError("the distributed solve lost all its Ray workers")
                    (min(queues.values(), key=len) if self.keep_groups else shared).extendleft(reversed(left))
                    continue
                parts[group[0]] = part
                rays += group_rays
                measured.append((group[0], group[1], seconds))
                progress.advance(group[2])
                idle.append(w)
        self.learn_costs(measured, nodes)
        self.phase_times.append((phase, began, time.perf_counter(), [seconds for *_, seconds in measured]))
        return np.concatenate([parts[b] for b in sorted(parts)]) if parts else np.zeros(0), rays

    def learn_costs(self, measured: list, nodes: list) -> None:
        """Each group's receivers' cost per node scaled so that their predicted seconds are the
        group's measured ones; receivers that did not gather (settled) by the phase's overall scale."""
        nodes = np.asarray(nodes, float)
        cost = self.cost_per_node
        gathered = np.zeros(len(cost), bool)
        predicted_sum = seconds_sum = 0.0
        for begin, end, seconds in measured:
            predicted = float((cost[begin:end] * nodes[begin:end]).sum())
            if predicted > 0 and seconds > 0:
                live = nodes[begin:end] > 0
                cost[begin:end][live] *= seconds / predicted
                gathered[begin:end] |= live
                predicted_sum, seconds_sum = predicted_sum + predicted, seconds_sum + seconds
        if predicted_sum > 0:
            cost[~gathered] *= seconds_sum / predicted_sum
