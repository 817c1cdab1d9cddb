"""Tests, benchmarks and tools talk only to this machine: no address but loopback in the code.

Every tracked-or-new Python file under integrators/, experiments/, benchmarks/,
tools/ and tests/ is scanned for

* IPv4 literals (anywhere, comments and docstrings included) other than 127.x.x.x;
* IPv6 literals (``[..]`` or bare with ``::``) other than ``::1``;
* hosts of URLs (``tcp://<host>:<port>``, ``http://<host>/``) other than loopback
  (``127.x``, ``localhost``, ``[::1]``); ``file://`` and placeholders in angle
  brackets (``tcp://<host>:8786``, for help texts) are fine;
* socket addresses written as a ``("host", port)`` tuple with a host that is not
  loopback.

The check fails naming file and line. Its negative control writes files that
hold such addresses (built at run time, so this file itself holds none) and
requires each to be caught.
"""
from __future__ import annotations

import ast
import ipaddress
import os
import re

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FOLDERS = ("integrators", "experiments", "benchmarks", "tools", "tests")

IPV4 = re.compile(r"(?<![\w.])(\d{1,3}(?:\.\d{1,3}){3})(?![\w.])")
IPV6 = re.compile(r"\[([0-9A-Fa-f:]*:[0-9A-Fa-f:.]*)\]|(?<![\w:])((?:[0-9A-Fa-f]{1,4})?::"
                  r"(?:[0-9A-Fa-f]{1,4}(?::[0-9A-Fa-f]{1,4})*)?)(?![\w:])")
URL = re.compile(r"\b([a-z][a-z0-9+.-]*)://(\[[^\]]*\]|<[^>]*>|[^/:\s'\"(){}\[\],]*)")
LOOPBACK_NAMES = {"localhost", "localhost.localdomain", "ip6-localhost"}


def is_loopback(host: str) -> bool:
    host = host.strip("[]")
    if host.lower() in LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _version_like(line: str, start: int) -> bool:
    """A dotted quad right after "v" or "=": part of a version string, not an address."""
    return line[max(0, start - 1):start] in ("v", "=")


def line_problems(line: str) -> list[str]:
    found = []
    for m in IPV4.finditer(line):
        text = m.group(1)
        try:
            address = ipaddress.ip_address(text)
        except ValueError:
            continue                     # not an address (an octet above 255)
        if not address.is_loopback and not _version_like(line, m.start(1)):
            found.append(f"IPv4 address {text}")
    for m in IPV6.finditer(line):
        text = m.group(1) or m.group(2)
        if text in ("::", "") or "::" not in text and text.count(":") < 2:
            continue                     # a slice [::] or a C++ scope, not an address
        try:
            address = ipaddress.ip_address(text)
        except ValueError:
            continue
        if not address.is_loopback:
            found.append(f"IPv6 address {text}")
    for m in URL.finditer(line):
        scheme, host = m.group(1), m.group(2)
        if scheme == "file" or host == "" or host.startswith("<") or is_loopback(host):
            continue
        found.append(f"URL host '{host}' ({scheme}://)")
    return found


HOSTNAME = re.compile(r"[A-Za-z0-9-]+(\.[A-Za-z0-9-]+)+")


def tuple_problems(tree: ast.AST) -> list[tuple[int, str]]:
    """``("host.domain", port)`` socket addresses whose host is not loopback (dotted quads
    are the line scan's)."""
    found = []
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Tuple) and len(node.elts) == 2):
            continue
        host, port = node.elts
        if (isinstance(host, ast.Constant) and isinstance(host.value, str)
                and isinstance(port, ast.Constant) and type(port.value) is int
                and HOSTNAME.fullmatch(host.value) and not IPV4.fullmatch(host.value)
                and not is_loopback(host.value)):
            found.append((node.lineno, f"socket address ('{host.value}', {port.value})"))
    return found


def file_problems(path: str) -> list[str]:
    with open(path, encoding="utf-8") as f:
        text = f.read()
    rel = os.path.relpath(path, ROOT)
    found = [f"{rel}:{i}: {what}" for i, line in enumerate(text.splitlines(), 1)
             for what in line_problems(line)]
    try:
        tree = ast.parse(text, path)
    except SyntaxError as e:
        return found + [f"{rel}:{e.lineno}: does not parse ({e.msg})"]
    return found + [f"{rel}:{line}: {what}" for line, what in tuple_problems(tree)]


def python_files(root: str = ROOT) -> list[str]:
    files = []
    for folder in FOLDERS:
        for directory, dirs, names in os.walk(os.path.join(root, folder)):
            dirs[:] = [d for d in dirs if d not in ("__pycache__",) and not d.startswith(".")]
            files += [os.path.join(directory, n) for n in names if n.endswith(".py")]
    return sorted(files)


def test_the_project_names_only_loopback_addresses():
    files = python_files()
    assert len(files) > 40          # the scan sees the project (not an empty folder)
    problems = [p for path in files for p in file_problems(path)]
    assert not problems, "non-loopback addresses in the code:\n" + "\n".join(problems)


def _dotted(*parts) -> str:
    return ".".join(map(str, parts))


NEGATIVE = [
    f"SCHEDULER = 'tcp://{_dotted(192, 0, 2, 1)}:8786'",
    f"HOST = '{_dotted(10, 1, 2, 3)}'  # a private range",
    f"url = 'http://{'example'}.org/x'",
    "sock.connect((" + repr(_dotted("example", "com")) + ", 80))",
    f"addr = '[{'2001:db8' + '::1'}]:8786'",
    f"c = Client('tcp://{'head'}:8786')",
]
POSITIVE = [
    "a = 'tcp://127.0.0.1:8786'", "b = 'http://localhost:8000/'", "c = 'tcp://[::1]:1'",
    "d = 'file://' + path", "e = x[::1]", "f = 'tcp://<host>:8786'", "g = 'mitsuba>=3.9.1'",
    "s.bind(('127.0.0.1', 0))", "h = ('llvm_ad_rgb', 4)",
]


@pytest.mark.parametrize("line", NEGATIVE)
def test_negative_control_a_non_loopback_address_is_caught(tmp_path, line):
    path = tmp_path / "tests" / "bad.py"
    path.parent.mkdir()
    path.write_text(f"import socket\n\n{line}\n")
    problems = file_problems(str(path))
    assert problems and all(":3:" in p for p in problems), problems
    assert [str(path)] == python_files(str(tmp_path))


@pytest.mark.parametrize("line", POSITIVE)
def test_loopback_and_placeholders_pass(tmp_path, line):
    path = tmp_path / "ok.py"
    path.write_text(line + "\n")
    assert file_problems(str(path)) == []
