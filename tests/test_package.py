import subprocess
import sys


def _run(code: str) -> str:
    return subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True).stdout


def test_importing_the_package_does_not_import_gymnasium_or_pybullet():
    out = _run(
        "import sys, negobs_gym, negobs_gym.core\n"
        "print('gymnasium' in sys.modules, 'pybullet' in sys.modules)"
    )
    assert out.split() == ["False", "False"]


def test_envs_are_registered_whichever_is_imported_first_and_registration_is_idempotent():
    from negobs_gym.registration import ALIASES, ENV_SPECS

    ids = sorted([spec[0] for spec in ENV_SPECS] + [alias[0] for alias in ALIASES])
    assert "negobs_gym/Braking-v0" in ids
    code = (
        "import {first}, {second}, gymnasium\n"
        "import negobs_gym.registration as r; r.register_envs(); r.register_envs()\n"
        "print(sorted(k for k in gymnasium.registry if k.startswith('negobs_gym/')))"
    )
    for first, second in (("negobs_gym", "gymnasium"), ("gymnasium", "negobs_gym")):
        out = _run(code.format(first=first, second=second))
        assert out.strip() == str(ids)
