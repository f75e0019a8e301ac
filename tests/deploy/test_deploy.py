"""deploy/: the systemd units, the settings file and the nginx site that docs/service.md's checklist installs
(issue #42). They must agree with the code and with each other:

- every ExecStart runs: the API's and the worker host's with `--check` (a dry start that parses the command line,
  reads the settings and the Redis URL's file, checks the data directory and exits 0 without serving), the
  backup's for real, with /srv/raytrace-edu, /etc/raytrace-edu and /var/backups/tracer moved into a temporary
  folder, under the environment its EnvironmentFile= gives (deploy/env.example, its token filled in), and nothing
  of this process's own TRACER_* environment;
- every TRACER_ name in deploy/ is a setting of server/core/settings.py;
- the nginx site passes Debian's `nginx -t` (a syntax check that starts nothing) inside a temporary nginx.conf
  with a self-signed certificate made by openssl, and proxies to the address the API's unit listens on;
- the documents name one install folder (/srv/raytrace-edu) and the deploy/ files they point to exist.

Never skipped: without nginx or openssl these fail and say so (`./dev test` installs nginx).
"""

from __future__ import annotations

import json
import os
import re
import secrets
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from server.core.settings import Settings
from tests.support.scene import ROOT

DEPLOY = ROOT / "deploy"
SYSTEMD = DEPLOY / "systemd"
SITE = DEPLOY / "nginx" / "raytrace-edu.conf"
ENV_EXAMPLE = DEPLOY / "env.example"
NGINX = "/usr/sbin/nginx"
INSTALL, ETC, BACKUPS = "/srv/raytrace-edu", "/etc/raytrace-edu", "/var/backups/tracer"
SETTINGS = {f"TRACER_{name.upper()}" for name in Settings.model_fields}


def unit(path: Path) -> dict[str, list[tuple[str, str]]]:
    """A systemd unit file's sections, each a list of (key, value) in order (keys repeat: ExecStart= resets)."""
    sections: dict[str, list[tuple[str, str]]] = {}
    current = None
    lines = path.read_text().splitlines()
    i = 0
    while i < len(lines):
        line = lines[i].strip()
        while line.endswith("\\") and i + 1 < len(lines):  # a continued line
            i += 1
            line = line[:-1] + " " + lines[i].strip()
        i += 1
        if not line or line[0] in "#;":
            continue
        if line.startswith("["):
            current = sections.setdefault(line.strip("[]"), [])
            continue
        key, sep, value = line.partition("=")
        assert sep and current is not None, f"{path.name}: not a key=value line in a section: {line!r}"
        current.append((key.strip(), value.strip()))
    return sections


def values(sections: dict, section: str, key: str) -> list[str]:
    return [v for k, v in sections.get(section, []) if k == key]


def exec_start(path: Path) -> str:
    """The ExecStart that systemd runs: the last one after the last empty one (a drop-in's reset), the unit's own
    where a drop-in does not replace it."""
    own = values(unit(path), "Service", "ExecStart")
    if path.suffix == ".conf":  # a drop-in: on top of its unit's
        own = values(unit(path.parent.parent / path.parent.name.removesuffix(".d")), "Service", "ExecStart") + own
    after_reset = own[len(own) - own[::-1].index("") :] if "" in own else own
    assert len(after_reset) == 1, f"{path.name}: one ExecStart, not {after_reset}"
    return after_reset[0]


def unescaped(command: str) -> str:
    """systemd's specifiers in a command line: `%%` is a `%`; any other is one this check does not know."""
    assert not re.search(r"%[^%]", command.replace("%%", "")), f"a systemd specifier other than %%: {command}"
    return command.replace("%%", "%")


class Machine:
    """The deployment's folders inside `tmp`: /srv/raytrace-edu (its .venv this checkout's), /etc/raytrace-edu
    (the settings file from deploy/env.example, the Redis URL's file), /var/backups/tracer."""

    def __init__(self, tmp: Path, token: str | None = None):
        self.install, self.etc, self.backups = tmp / "srv", tmp / "etc", tmp / "backups"
        for d in (self.install, self.etc, self.backups):
            d.mkdir()
        (self.install / ".venv").symlink_to(Path(sys.executable).parent.parent)  # the checkout's .venv
        env = self.moved(ENV_EXAMPLE.read_text())
        if token is not None:
            env = re.sub(r"(?m)^TRACER_INSTRUCTOR_TOKEN=.*$", f"TRACER_INSTRUCTOR_TOKEN={token}", env)
        (self.etc / "env").write_text(env)
        (self.etc / "redis-url").write_text("redis://:a-password@127.0.0.1:1/0\n")  # --check never connects

    def moved(self, text: str) -> str:
        return text.replace(INSTALL, str(self.install)).replace(ETC, str(self.etc)).replace(BACKUPS, str(self.backups))

    def environment(self, path: Path) -> dict[str, str]:
        """PATH and HOME, and what the unit's EnvironmentFile= and Environment= set (systemd's simple syntax)."""
        env = {"PATH": os.environ.get("PATH", "/usr/bin:/bin"), "HOME": str(self.install), "LANG": "C.UTF-8"}
        sections = unit(path)
        for name in values(sections, "Service", "EnvironmentFile"):
            for line in Path(self.moved(name.lstrip("-"))).read_text().splitlines():
                if line.strip() and not line.lstrip().startswith(("#", ";")):
                    key, _, value = line.partition("=")
                    env[key.strip()] = value.strip()
        for assignment in values(sections, "Service", "Environment"):
            for word in shlex.split(assignment):
                key, _, value = word.partition("=")
                env[key] = value
        return env

    def run(self, path: Path, *extra: str, command: str | None = None) -> subprocess.CompletedProcess:
        """The unit's ExecStart (or `command`) as systemd would run it, in its WorkingDirectory, moved here."""
        sections = unit(self.base(path))
        cwd = self.moved(values(sections, "Service", "WorkingDirectory")[-1])
        words = shlex.split(self.moved(unescaped(command or exec_start(path)))) + list(extra)
        return subprocess.run(
            words, cwd=cwd, env=self.environment(self.base(path)), capture_output=True, text=True, timeout=120
        )

    @staticmethod
    def base(path: Path) -> Path:
        return path.parent.parent / path.parent.name.removesuffix(".d") if path.suffix == ".conf" else path


SERVICES = sorted(SYSTEMD.glob("*.service"))
STARTS = [p for p in [*SERVICES, *sorted(SYSTEMD.glob("*.service.d/*.conf"))] if "backup" not in p.name]


def test_deploy_has_the_units_the_docs_show():
    names = {p.relative_to(SYSTEMD).as_posix() for p in SYSTEMD.rglob("*") if p.is_file()}
    assert names == {
        "tracer-api.service",
        "tracer-api.service.d/redis.conf",
        "tracer-worker.service",
        "tracer-backup.service",
        "tracer-backup.timer",
    }
    for path in SERVICES:
        s = unit(path)
        assert values(s, "Service", "User") == ["tracer"], path.name
        assert values(s, "Service", "WorkingDirectory") == [INSTALL], path.name
    for path in (SYSTEMD / "tracer-api.service", SYSTEMD / "tracer-worker.service"):
        s = unit(path)
        assert values(s, "Service", "KillMode") == ["control-group"], path.name  # the horse and the workers stop
        assert values(s, "Install", "WantedBy") == ["multi-user.target"], path.name
    timer = unit(SYSTEMD / "tracer-backup.timer")
    assert values(timer, "Timer", "OnCalendar") == ["*-*-* 03:15:00"]
    assert values(timer, "Timer", "Persistent") == ["true"]
    assert values(timer, "Install", "WantedBy") == ["timers.target"]
    assert values(unit(SYSTEMD / "tracer-backup.service"), "Service", "Type") == ["oneshot"]


@pytest.mark.parametrize("path", STARTS, ids=lambda p: p.relative_to(SYSTEMD).as_posix())
def test_deploy_each_start_command_is_a_real_command_that_parses(path, tmp_path):
    m = Machine(tmp_path, token=secrets.token_urlsafe(32))
    words = shlex.split(exec_start(path))
    assert words[0] == f"{INSTALL}/.venv/bin/python" and words[1] == "-m", words
    assert words[2] in ("server", "server.worker"), words
    done = m.run(path, "--check")
    assert done.returncode == 0, done.stderr
    assert "check: would " in done.stderr, done.stderr
    assert "Traceback" not in done.stderr
    if words[2] == "server":
        assert f"data in {m.install / 'data'}" in done.stderr, done.stderr  # TRACER_DATA_DIR from the env file
        assert (m.install / "data").is_dir()
    if "--redis-url-file" in words:
        assert "a-password" not in done.stderr and "***" in done.stderr, done.stderr  # the URL's file was read


def test_deploy_systemd_analyze_verify_finds_nothing_to_say(tmp_path):
    """systemd's own check of the units (every key known, every value parsed, the timer's calendar), with their
    folders moved into `tmp_path`: it warns on stderr (status 0) about what it ignores, so any output fails."""
    analyze = shutil.which("systemd-analyze")
    if analyze is None:
        pytest.fail("systemd-analyze is missing: install Debian's systemd package (./dev test does it)")
    m = Machine(tmp_path, token=secrets.token_urlsafe(32))
    units = tmp_path / "units"
    units.mkdir()
    for path in [*SYSTEMD.glob("*.service"), *SYSTEMD.glob("*.timer")]:
        (units / path.name).write_text(m.moved(path.read_text()))
    files = sorted(str(p) for p in units.iterdir())
    done = subprocess.run([analyze, "verify", "--man=no", *files], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and not done.stderr.strip() and not done.stdout.strip(), done.stderr + done.stdout
    api = (units / "tracer-api.service").read_text()
    (units / "tracer-api.service").write_text(api.replace("KillMode=control-group", "KillMode=group"))
    bad = subprocess.run([analyze, "verify", "--man=no", str(units / "tracer-api.service")], capture_output=True,
                         text=True, timeout=120)  # fmt: skip
    assert "kill mode" in bad.stderr, bad.stderr  # the check does check


def test_deploy_the_env_example_s_placeholder_token_stops_the_start(tmp_path):
    """Installed unchanged, the settings file keeps the API from starting (behind nginx on loopback a server
    without a token would make everyone the instructor): the message names the setting."""
    m = Machine(tmp_path)  # the placeholder left as it is
    done = m.run(SYSTEMD / "tracer-api.service", "--check")
    assert done.returncode != 0
    assert "TRACER_INSTRUCTOR_TOKEN" in done.stderr and "Traceback" not in done.stderr, done.stderr


def test_deploy_a_start_command_with_a_wrong_option_fails_the_check(tmp_path):
    """--check parses what it is given: a misspelt option is an error, not a start."""
    m = Machine(tmp_path, token=secrets.token_urlsafe(32))
    path = SYSTEMD / "tracer-api.service"
    done = m.run(path, "--check", command=exec_start(path) + " --threads 4")
    assert done.returncode == 2 and "unrecognized arguments: --threads 4" in done.stderr, done.stderr


def test_deploy_the_backup_unit_backs_up_and_keeps_the_last_14(tmp_path):
    m = Machine(tmp_path, token=secrets.token_urlsafe(32))
    path = SYSTEMD / "tracer-backup.service"
    words = shlex.split(exec_start(path))
    assert words[:2] == ["/bin/sh", "-c"] and ".venv/bin/python -m server backup " in words[2], words
    python = str(m.install / ".venv" / "bin" / "python")
    data = m.install / "data"
    made = subprocess.run([python, "-m", "server", "migrate", "--data-dir", str(data)], capture_output=True, text=True)
    assert made.returncode == 0, made.stderr
    for day in range(1, 16):  # 15 older nightly backups
        (m.backups / f"2026-11-{day:02d}").mkdir()
    done = m.run(path)
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout.splitlines()[0])
    dest = Path(summary["backup"])
    assert dest.parent == m.backups and re.fullmatch(r"\d{4}-\d{2}-\d{2}", dest.name), dest  # %%F: the UTC date
    assert (dest / "manifest.json").is_file()
    assert (dest / "jobs.sqlite3").is_file()
    kept = sorted(p.name for p in m.backups.iterdir())
    assert len(kept) == 14 and kept[-1] == dest.name and kept[0] == "2026-11-03", kept


def test_deploy_every_tracer_name_is_a_setting():
    for path in [*DEPLOY.rglob("*")]:
        if path.is_file():
            names = set(re.findall(r"\bTRACER_[A-Z0-9_]+", path.read_text()))
            unknown = names - SETTINGS
            assert not unknown, f"{path.relative_to(ROOT)}: not settings of server/core/settings.py: {unknown}"
    env = [line.partition("=")[0].lstrip("#") for line in ENV_EXAMPLE.read_text().splitlines() if "=" in line]
    assert {"TRACER_INSTRUCTOR_TOKEN", "TRACER_ALLOWED_HOSTS", "TRACER_DATA_DIR"} <= set(env)


def test_deploy_the_nginx_site_agrees_with_the_api_and_the_settings():
    site = SITE.read_text()
    api = shlex.split(exec_start(SYSTEMD / "tracer-api.service"))
    host, port = api[api.index("--host") + 1], api[api.index("--port") + 1]
    assert re.findall(r"proxy_pass\s+([^;]+);", site) == [f"http://{host}:{port}"]
    body = re.search(r"client_max_body_size\s+(\d+)m;", site)
    s = Settings()
    assert int(body[1]) * 1024 * 1024 >= int(s.max_class_bytes) + s.max_body_bytes  # a class's zip passes nginx
    env = dict(line.split("=", 1) for line in ENV_EXAMPLE.read_text().splitlines() if line.startswith("TRACER_"))
    names = set(re.findall(r"server_name\s+([^;]+);", site))
    assert names == {env["TRACER_ALLOWED_HOSTS"]}, names  # the API answers the names nginx serves


def nginx_check(tmp: Path, site_text: str) -> subprocess.CompletedProcess:
    """`nginx -t` on a temporary nginx.conf that includes the site, its certificate a self-signed one."""
    if not Path(NGINX).exists():
        pytest.fail(f"{NGINX} is missing: install Debian's nginx package (./dev test does it)")
    openssl = shutil.which("openssl")
    if openssl is None:
        pytest.fail("openssl is missing: install Debian's openssl package")
    cert, key = tmp / "cert.pem", tmp / "key.pem"
    if not cert.exists():
        made = subprocess.run(
            [openssl, "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1", "-subj", "/CN=render.example.edu",
             "-keyout", str(key), "-out", str(cert)],
            capture_output=True, text=True, timeout=60,
        )  # fmt: skip
        assert made.returncode == 0, made.stderr
    site_text = re.sub(r"ssl_certificate\s+[^;]+;", f"ssl_certificate {cert};", site_text)
    site_text = re.sub(r"ssl_certificate_key\s+[^;]+;", f"ssl_certificate_key {key};", site_text)
    (tmp / "site.conf").write_text(site_text)
    (tmp / "nginx.conf").write_text(
        f"""pid {tmp}/nginx.pid;
error_log {tmp}/error.log;
events {{ worker_connections 4096; }}
http {{
    access_log {tmp}/access.log;
    client_body_temp_path {tmp}/body;
    proxy_temp_path {tmp}/proxy;
    fastcgi_temp_path {tmp}/fastcgi;
    uwsgi_temp_path {tmp}/uwsgi;
    scgi_temp_path {tmp}/scgi;
    include {tmp}/site.conf;
}}
"""
    )
    return subprocess.run(
        [NGINX, "-t", "-q", "-p", str(tmp), "-e", str(tmp / "error.log"), "-c", str(tmp / "nginx.conf")],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip


def test_deploy_the_nginx_site_passes_nginx_t(tmp_path):
    site = SITE.read_text()
    assert "ssl_certificate " in site
    assert "ssl_certificate_key " in site
    done = nginx_check(tmp_path, site)
    assert done.returncode == 0, done.stderr
    assert "[emerg]" not in done.stderr and "[warn]" not in done.stderr, done.stderr
    broken = nginx_check(tmp_path, site.replace("proxy_buffering off;", "proxy_buffering of;"))
    assert broken.returncode != 0 and "proxy_buffering" in broken.stderr, broken.stderr  # the check does check


def test_deploy_the_docs_name_one_install_folder_and_its_files():
    docs = {p: p.read_text() for p in [*ROOT.glob("docs/*.md"), ROOT / "README.md", *DEPLOY.rglob("*")] if p.is_file()}
    for path, text in docs.items():
        assert "/srv/tracer" not in text, f"{path.relative_to(ROOT)}: the install folder is {INSTALL}"
        for name in re.findall(r"(?<![\w/])deploy/[\w./-]*\w", text):
            assert (ROOT / name).exists(), f"{path.relative_to(ROOT)} names {name}, which is not in the repository"
    service = docs[ROOT / "docs" / "service.md"]
    for path in [*SYSTEMD.rglob("*.service"), *SYSTEMD.rglob("*.timer"), *SYSTEMD.rglob("*.conf"), SITE, ENV_EXAMPLE]:
        assert path.relative_to(ROOT).as_posix() in service, f"docs/service.md does not point to {path.name}"
