"""Reproduce, in one process, the reported hang of pycinder's queries next to Warp on CUDA.

The reported case: in one process, ``benchmarks.peers.Pycinder("a")``, then
``Pycinder("b", planner="gpu")``, then ``warp_peer.Warp()``, then ``FCL()``, in that order;
then ManyBodies(1000) and Stairs(250) queried by each. pycinder's waits run under ``--deadline``
seconds: a wait that passes it raises ``GpuTimeoutError``, whose message says whether the device
was lost, which passes its submission held and whether the GPU started and finished it (printed
here with the timings). A hang inside a native call, where no deadline reaches, is shown by a
dump of every thread's stack after ``--dump-after`` seconds (faulthandler).

Steps to narrow it down (one per run)::

    python scripts/repro-warp-hang.py                         # the reported case
    python scripts/repro-warp-hang.py --only warp-init        # Warp's wp.init() alone, no Warp peer
    python scripts/repro-warp-hang.py --only second-detector  # the second Detector alone, no Warp
    python scripts/repro-warp-hang.py --no-mempools           # WARP_ENABLE_MEMPOOLS_AT_INIT=0
    python scripts/repro-warp-hang.py --cuda-first            # Warp initialised before the device

It exits 0 when every query answered, 1 when one timed out or failed.
"""

from __future__ import annotations

import argparse
import faulthandler
import os
import sys
import time
import traceback
from typing import Any

# The benchmark harness lives in the checkout, beside this script's folder.
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

STEPS = ("all", "warp-init", "second-detector")


def parse(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--only", choices=STEPS, default="all",
                   help="all: the reported case; warp-init: pycinder 'a' and wp.init() alone; "
                        "second-detector: pycinder 'a' and 'b' alone (default: all)")
    p.add_argument("--deadline", type=float, default=60.0,
                   help="seconds any one GPU wait of pycinder may take (default 60)")
    p.add_argument("--dump-after", type=float, default=None,
                   help="dump every thread's stack after this many seconds (default: twice the "
                        "deadline, plus 30)")
    p.add_argument("--no-mempools", action="store_true",
                   help="set WARP_ENABLE_MEMPOOLS_AT_INIT=0 before Warp is imported")
    p.add_argument("--cuda-first", action="store_true",
                   help="initialise Warp (CUDA) before pycinder makes its device")
    p.add_argument("--frames", type=int, default=2, help="frames queried per scene (default 2)")
    p.add_argument("--bodies", type=int, default=1000,
                   help="bodies of the ManyBodies scene (default 1000)")
    p.add_argument("--stairs", type=int, default=250,
                   help="spheres of the Stairs scene (default 250)")
    args = p.parse_args(argv)
    if args.deadline <= 0 or args.frames < 1 or args.bodies < 2 or args.stairs < 2:
        p.error("--deadline must be positive, --frames at least 1, --bodies and --stairs at "
                "least 2")
    if args.dump_after is None:
        args.dump_after = 2 * args.deadline + 30
    return args


def say(message: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {message}", flush=True)


def init_warp() -> Any:
    """``wp.init()``, timed; the module, and the CUDA devices Warp sees."""
    t0 = time.perf_counter()
    import warp as wp

    wp.init()
    say(f"wp.init(): {time.perf_counter() - t0:.2f} s; Warp {wp.config.version}, "
        f"{wp.get_cuda_device_count()} CUDA device(s)")
    return wp


def make_systems(args: argparse.Namespace) -> list[Any]:
    """The systems of the step asked for, made in the reported order, each timed."""
    from benchmarks.peers import FCL, Pycinder

    systems = []

    def made(name: str, make: Any) -> None:
        t0 = time.perf_counter()
        try:
            systems.append(make())
        except Exception as exc:  # a peer that cannot be made here is named and left out
            say(f"{name}: could not be made ({type(exc).__name__}: {exc})")
            return
        say(f"{name}: made in {time.perf_counter() - t0:.2f} s")

    if args.cuda_first and args.only != "second-detector":
        init_warp()
    made("Pycinder('a')", lambda: Pycinder("a", timeout=args.deadline))
    if args.only in ("all", "second-detector"):
        made("Pycinder('b', planner='gpu')",
             lambda: Pycinder("b", planner="gpu", timeout=args.deadline))
    if args.only == "warp-init" and not args.cuda_first:
        init_warp()
    if args.only == "all":
        from benchmarks.warp_peer import Warp

        made("Warp()", Warp)
        made("FCL()", FCL)
    from pycinder.gpu.device import get_gpu

    say(f"pycinder's device: {get_gpu().description}")
    return systems


def query(systems: list[Any], args: argparse.Namespace) -> bool:
    """Every system on every frame of both scenes; True when all answered."""
    from pycinder.testing.scenes import ManyBodies, Stairs
    from pycinder.errors import GpuTimeoutError

    ok = True
    for scene in (ManyBodies(args.bodies, frames=args.frames),
                  Stairs(args.stairs, frames=args.frames)):
        for system in systems:
            t0 = time.perf_counter()
            try:
                system.prepare(scene)
                times = []
                for k in range(args.frames):
                    t1 = time.perf_counter()
                    pairs = system.step(scene, k)
                    times.append((time.perf_counter() - t1) * 1e3)
                say(f"{scene.name} / {system.name}: prepared in "
                    f"{(time.perf_counter() - t0) * 1e3 - sum(times):.0f} ms; frames "
                    f"{', '.join(f'{t:.1f}' for t in times)} ms; {len(pairs)} pairs")
            except GpuTimeoutError as exc:
                ok = False
                say(f"{scene.name} / {system.name}: TIMED OUT after "
                    f"{time.perf_counter() - t0:.1f} s\n  {exc}\n  device lost: "
                    f"{exc.device_lost}; progress: {exc.progress}")
            except Exception as exc:
                ok = False
                say(f"{scene.name} / {system.name}: FAILED ({type(exc).__name__}: {exc})")
                traceback.print_exc()
    return ok


def main(argv: list[str] | None = None) -> int:
    args = parse(argv)
    if args.no_mempools:
        os.environ["WARP_ENABLE_MEMPOOLS_AT_INIT"] = "0"
    os.environ.setdefault("XDG_RUNTIME_DIR", "/tmp")
    faulthandler.enable()
    faulthandler.dump_traceback_later(args.dump_after, exit=False)
    say(f"repro-warp-hang: --only {args.only}, deadline {args.deadline:g} s, stacks dumped "
        f"after {args.dump_after:g} s, mempools "
        f"{'off' if args.no_mempools else 'as Warp sets them'}, "
        f"{'Warp first' if args.cuda_first else 'pycinder first'}")
    try:
        ok = query(make_systems(args), args)
    finally:
        faulthandler.cancel_dump_traceback_later()
    say("every query answered" if ok else "some query timed out or failed")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
