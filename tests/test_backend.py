"""The XLA:CPU settings made at import: one CPU device per core, loops compiled whole without FMA
(x86-64), and never over a choice the user made (each case in a fresh interpreter: they are
process-wide). That whole loops keep every result bitwise is what the bitwise tests of
``jb.run`` against ``jb.orbit`` and of batches against single orbits check, in this configuration."""

import json
import os
import platform
import subprocess
import sys

REPORT = (
    "import json, os, jax; {before}import jaxbill as jb; "
    "print(json.dumps({{'devices': len(jax.devices()), 'x64': str(jax.numpy.zeros(1).dtype), "
    "'settings': jb.backend_settings(), "
    "'flags': os.environ.get('XLA_FLAGS', '')}}))"
)


def _fresh(env_changes=None, before="", report=REPORT):
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("XLA_FLAGS", "JAX_NUM_CPU_DEVICES", "JAXBILL_COMPILE_LOOPS_WHOLE", "JAXBILL_NO_XLA_SETTINGS")
    }
    env.update(env_changes or {})
    out = subprocess.run(
        [sys.executable, "-c", report.format(before=before)],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


X86 = platform.machine().lower() in ("x86_64", "amd64")


def test_one_cpu_device_per_core_and_whole_loops_without_fma_by_default():
    report = _fresh()
    assert report["devices"] == len(os.sched_getaffinity(0)) and report["x64"] == "float64"
    if X86:
        assert "xla_cpu_small_while_loop_byte_threshold=1000000000" in report["flags"]
        assert "--xla_cpu_max_isa=AVX" in report["flags"].split()
        assert report["settings"]["small_loops"].startswith("set")
    else:
        assert "small_while_loop" not in report["flags"] and "max_isa" not in report["flags"]
        assert report["settings"]["small_loops"].startswith("not set")


def test_whole_loops_opt_out_and_users_choices_kept():
    report = _fresh({"JAXBILL_COMPILE_LOOPS_WHOLE": "0"})
    assert "small_while_loop" not in report["flags"] and "max_isa" not in report["flags"]
    assert report["settings"]["small_loops"] == "not set (JAXBILL_COMPILE_LOOPS_WHOLE=0)"
    for users in ("--xla_backend_extra_options=xla_cpu_small_while_loop_byte_threshold=7", "--xla_cpu_max_isa=AVX2"):
        report = _fresh({"XLA_FLAGS": users, "JAX_NUM_CPU_DEVICES": "1"})
        assert report["flags"] == users and report["devices"] == 1
        assert report["settings"] == {
            "small_loops": "left to the user's XLA_FLAGS",
            "cpu_devices": "left to the user's choice",
        }


def test_too_late_when_the_backend_has_started_and_opting_out():
    report = _fresh(before="jax.devices(); ")
    assert report["x64"] == "float64"  # an option JAX takes at any time
    assert report["devices"] == 1 and report["settings"]["cpu_devices"].startswith("not set: JAX's backend had started")
    report = _fresh({"JAXBILL_NO_XLA_SETTINGS": "1"})
    assert report["devices"] == 1 and "JAXBILL_NO_XLA_SETTINGS" in report["settings"]["cpu_devices"]


def test_settings_hold_when_jax_is_imported_after_jaxbill():
    """``import jaxbill`` loads no JAX (it stays quick); float64 and the backend's settings still hold once
    JAX comes, through the variables JAX reads at its import."""
    report = _fresh(
        report="import sys; import jaxbill as jb; jax_before = 'jax' in sys.modules; "
        "import json, os, jax; print(json.dumps({{'jax_before': jax_before, 'devices': len(jax.devices()), "
        "'x64': str(jax.numpy.zeros(1).dtype), 'settings': jb.backend_settings(), "
        "'flags': os.environ.get('XLA_FLAGS', '')}}))"
    )
    assert report["jax_before"] is False
    assert report["x64"] == "float64" and report["devices"] == len(os.sched_getaffinity(0))
    assert report["settings"]["cpu_devices"] == f"set ({len(os.sched_getaffinity(0))}, one per core)"
    if X86:
        assert "--xla_cpu_max_isa=AVX" in report["flags"].split()
