"""What the command-line tests share: a command run in process, and the check of a refusal (one
line on stderr starting "error: ", exit 2, naming the words given)."""
from click.testing import CliRunner

from simucal.cli import main


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def refused(r, *words) -> str:
    """The one line of a refusal (beyond a derivation's own status lines, said with its time limit), holding each
    of words."""
    assert r.exit_code == 2 and isinstance(r.exception, SystemExit), (r.exit_code, r.output, r.exception)
    lines = [x for x in r.stderr.splitlines() if x.strip() and not x.startswith("deriving ")]
    assert len(lines) == 1 and lines[0].startswith("error: "), r.stderr
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]
