"""The XLA:CPU settings jaxbill makes at import, before JAX starts its backend.

1. **Every core a device.** JAX shows one CPU device unless told otherwise,
   and a batch split over the devices (``jb.run``, ``jb.orbit``) then uses
   one core. jaxbill asks for one CPU device per core available to the
   process. This changes no result: an orbit is bitwise the same on any
   number of devices (``jaxbill._engine.sharding``).
2. **Loops compiled whole, without fused multiply-adds** (x86-64).
   XLA:CPU compiles a ``while_loop`` whose carry is small into one native
   function; a larger loop runs each of its kernels as a separate call per
   iteration. An orbit's loop carries its records, so every collision paid
   about forty calls: raising the byte threshold
   (``--xla_backend_extra_options=xla_cpu_small_while_loop_byte_threshold=...``)
   makes one orbit's loop one native function, many times faster (single
   orbits are timed by ``benchmarks/bench_vs_numba.py``). Whole
   loops alone would cost bitwise reproducibility: LLVM optimises each loop
   in its own context and contracts multiply-adds into FMAs differently in
   different programs, so ``jb.run`` and ``jb.orbit`` of one orbit, or a
   batch and its single orbits, would agree only to the last bit. So jaxbill
   also caps the instruction set at AVX (``--xla_cpu_max_isa=AVX``), which
   has no FMA: every program then rounds every operation the same way, and
   float64 vector width is unchanged. The cost: LLVM then evaluates a
   float64 ``sqrt`` lane by lane in a vectorised loop, where at AVX2 it takes
   the lanes together (a spinning stick's lockstep batch, three square roots a
   root step, ran faster at AVX-512 with FMAs; ``benchmarks/HISTORY.md`` has
   the measurement), and JAX code of your own in the same process runs
   without FMA and AVX2 too (float32 matrix products slow down most). No
   XLA option turns FMA contraction off at AVX2 (``docs/performance.md``).
   Other CPUs (ARM) have no FMA-free level to cap at, so there jaxbill sets
   neither option.

Where JAX is not imported yet, jaxbill makes the device count (and float64)
through the variables JAX reads at its import (``JAX_NUM_CPU_DEVICES``,
``JAX_ENABLE_X64``), so that ``import jaxbill`` stays quick; child processes
inherit them, as they inherit ``XLA_FLAGS``, and there read as a choice
already made.

Both are process-wide and take effect only if set before the backend starts
(the first computation, or ``jax.devices()``). jaxbill never overrides a
choice the user made: an ``XLA_FLAGS`` that already names
``xla_backend_extra_options`` or ``xla_cpu_max_isa`` keeps setting 2 off,
and a device count given through ``XLA_FLAGS``
(``xla_force_host_platform_device_count``), the ``JAX_NUM_CPU_DEVICES``
variable or ``jax.config`` is left as it is. Import jaxbill after JAX has
started its backend and nothing can be set: the results are the same, only
single orbits run at the old speed and a batch uses one core
(``backend_settings()`` says what happened). ``JAXBILL_COMPILE_LOOPS_WHOLE=0``
turns setting 2 off; ``JAXBILL_NO_XLA_SETTINGS=1`` makes no setting at all.
"""

from __future__ import annotations

import os
import platform
import sys

SMALL_LOOP_OPTION = "xla_cpu_small_while_loop_byte_threshold=1000000000"
NO_FMA_OPTION = "--xla_cpu_max_isa=AVX"

_settings: dict[str, str] = {}


def _jax_imported() -> bool:
    return "jax" in sys.modules


def _set_jax_option(name: str, value: bool | int) -> None:
    """Set one of JAX's options: through its environment variable while JAX is not imported yet.

    JAX reads ``JAX_<NAME>`` when it is first imported, so the option holds from then on
    without importing JAX now (``import jaxbill`` stays quick); the variable is inherited
    by child processes, as ``XLA_FLAGS`` is.
    """
    if _jax_imported():
        import jax

        jax.config.update(f"jax_{name}", value)
    else:
        os.environ[f"JAX_{name.upper()}"] = str(int(value))


def _backend_started() -> bool:
    if not _jax_imported():  # no backend without JAX
        return False
    try:
        from jax._src import xla_bridge  # private: read-only use, guarded

        return bool(xla_bridge.backends_are_initialized())
    except (ImportError, AttributeError):  # a JAX without this helper: assume the worst
        return True


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def configure() -> None:
    """Switch JAX to float64, then make both settings where the user has not and the backend has not started."""
    _set_jax_option("enable_x64", True)
    if os.environ.get("JAXBILL_NO_XLA_SETTINGS"):
        not_set = "not set (JAXBILL_NO_XLA_SETTINGS)"
        _settings.update(small_loops=not_set, cpu_devices=not_set)
        return
    if _backend_started():
        late = "not set: JAX's backend had started before jaxbill was imported"
        _settings.update(small_loops=late, cpu_devices=late)
        return
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_backend_extra_options" in flags or "xla_cpu_max_isa" in flags:
        _settings["small_loops"] = "left to the user's XLA_FLAGS"
    elif os.environ.get("JAXBILL_COMPILE_LOOPS_WHOLE", "1") == "0":
        _settings["small_loops"] = "not set (JAXBILL_COMPILE_LOOPS_WHOLE=0)"
    elif platform.machine().lower() not in ("x86_64", "amd64"):
        _settings["small_loops"] = f"not set: {platform.machine()} has no FMA-free instruction set to cap XLA at"
    else:
        os.environ["XLA_FLAGS"] = f"{flags} --xla_backend_extra_options={SMALL_LOOP_OPTION} {NO_FMA_OPTION}".strip()
        _settings["small_loops"] = f"set ({SMALL_LOOP_OPTION}, {NO_FMA_OPTION.lstrip('-')})"
    user_chose_devices = (
        "xla_force_host_platform_device_count" in flags
        or "JAX_NUM_CPU_DEVICES" in os.environ
        or (_jax_imported() and _jax_num_cpu_devices() != -1)
    )
    if user_chose_devices:
        _settings["cpu_devices"] = "left to the user's choice"
    else:
        cores = _cores()
        _set_jax_option("num_cpu_devices", cores)
        _settings["cpu_devices"] = f"set ({cores}, one per core)"


def _jax_num_cpu_devices() -> int:
    import jax

    # jax declares its options as dynamic attributes, which pyright cannot see
    return jax.config.jax_num_cpu_devices  # pyright: ignore[reportAttributeAccessIssue]


def backend_settings() -> dict[str, str]:
    """What jaxbill set at import: ``{"small_loops": ..., "cpu_devices": ...}``, each a short sentence."""
    return dict(_settings)
