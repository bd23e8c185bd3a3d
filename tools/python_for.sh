#!/bin/sh
# Print the path of a CPython interpreter of version $1 (e.g. 3.12) for `make test-py` (docs/decisions/
# emulator-runtime.md D-7.31). Looked for, in order: `python$1` on PATH, then pyenv's versions ($PYENV_ROOT, else
# ~/.pyenv). When none is found and pyenv is installed, `pyenv install --skip-existing $1` builds it (minutes: it
# compiles CPython). Debian 12, the CI machine's system, ships neither 3.12 nor 3.13, so apt-get is no way to them.
# Otherwise: a message saying how to get it on stderr and exit status 2 (CI fails: requires-python claims what
# CI tests, so a missing version is a failure, not a skip).
set -eu
want=${1:?usage: tools/python_for.sh MAJOR.MINOR}
case $want in
    3.[0-9]|3.[0-9][0-9]) ;;
    *) echo "python_for: '$want' is not a MAJOR.MINOR Python version (e.g. 3.12)" >&2; exit 2 ;;
esac

is_version() {  # $1: an interpreter; true when it runs and is version $want
    [ -x "$1" ] && [ "$("$1" -c 'import sys; print("%d.%d" % sys.version_info[:2])' 2>/dev/null)" = "$want" ]
}

found() {
    if command -v "python$want" >/dev/null 2>&1; then
        p=$(command -v "python$want")
        # a pyenv shim answers on PATH even when the version is not the active one: check it runs
        if is_version "$p"; then echo "$p"; return 0; fi
    fi
    root=${PYENV_ROOT:-$HOME/.pyenv}
    # newest patch release first
    for d in $(ls -d "$root/versions/$want".* "$root/versions/$want" 2>/dev/null | sort -t. -k3 -n -r); do
        if is_version "$d/bin/python$want"; then echo "$d/bin/python$want"; return 0; fi
    done
    return 1
}

if found; then exit 0; fi
if command -v pyenv >/dev/null 2>&1; then
    echo "python_for: no Python $want here; building it with pyenv (several minutes)" >&2
    if pyenv install --skip-existing "$want" >&2 && found; then exit 0; fi
fi
echo "python_for: no Python $want found (PATH, \$PYENV_ROOT/versions) and pyenv could not build it:" \
     "install it (pyenv install $want, or your system's python$want with its venv module)" >&2
exit 2
