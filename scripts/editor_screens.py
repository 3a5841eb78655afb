"""Re-make the pictures of `hfsmc lsp` in Neovim that docs/editors.md shows.

    .venv/bin/python scripts/editor_screens.py [--out docs/editors] [--keep DIR]

Needs Neovim installed by hand (Debian 12: ``apt-get install neovim``, 0.7.2 made
the committed pictures), tmux and chromium; ``hfsmc`` is the one beside this
Python. Not part of ``make test`` or ``make setup``: Neovim is not a dependency.

What it does, in a temporary copy of examples/follow_colors and examples/lib, with
a temporary HOME whose ``init.lua`` is the Neovim configuration of docs/editors.md
(taken from the page, so the pictures show the documented setup; one line more
gives a float grey colours instead of Neovim 0.7's red on magenta):

1. Neovim in tmux (110x30) opens follow_colors.yaml with ``to: Done`` misspelt
   ``to: Dnoe``; once the server's diagnostics show, the cursor goes to ``Dnoe``
   and ``vim.diagnostic.open_float()`` shows the whole message: that screen is
   ``neovim-diagnostic.png``.
2. In the same Neovim, split in two windows (one on ``Mission:``, one on the
   ``link back`` transition), ``<F2>`` (``vim.lsp.buf.rename``) renames the state
   ``Mission`` to ``Flight``; the renamed names are highlighted by a search for
   ``Flight``: that screen is ``neovim-rename.png``.

Each screen is captured with its colours (``tmux capture-pane -e``), turned into
an SVG of a terminal with rich, and photographed by headless chromium as a PNG.
"""

from __future__ import annotations

import argparse
import io
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from rich.console import Console
from rich.text import Text

ROOT = Path(__file__).resolve().parent.parent
COLS, ROWS = 110, 30
TIMEOUT = 30.0
# The colour of an underline (SGR 58, Neovim's undercurl of a diagnostic): rich reads
# its numbers as other attributes, so it is dropped.
_UNDERLINE_COLOUR = re.compile(r"\x1b\[58(?:;5;\d+|;2;\d+;\d+;\d+)m")
# Neovim 0.7 draws a float in red on magenta, hard to read in a picture: grey here.
_FLOAT_COLOURS = '\n-- for the picture only\nvim.cmd("highlight NormalFloat ctermbg=238 ctermfg=255")\n'
# rich's terminal SVG, with a font every Debian machine has (DejaVu Sans Mono) and
# nothing fetched from the network.
_SVG = """\
<svg class="rich-terminal" viewBox="0 0 {width} {height}" xmlns="http://www.w3.org/2000/svg">
    <style>
    .{unique_id}-matrix {{
        font-family: "DejaVu Sans Mono", monospace;
        font-size: {char_height}px;
        line-height: {line_height}px;
    }}
    .{unique_id}-title {{
        font-size: 18px;
        font-weight: bold;
        font-family: "DejaVu Sans", sans-serif;
    }}
    {styles}
    </style>
    <defs>
    <clipPath id="{unique_id}-clip-terminal">
      <rect x="0" y="0" width="{terminal_width}" height="{terminal_height}" />
    </clipPath>
    {lines}
    </defs>
    {chrome}
    <g transform="translate({terminal_x}, {terminal_y})" clip-path="url(#{unique_id}-clip-terminal)">
    {backgrounds}
    <g class="{unique_id}-matrix">
    {matrix}
    </g>
    </g>
</svg>
"""


class Failed(Exception):
    """A step of the script did not happen; the message says which."""


def neovim_config() -> str:
    """The ``init.lua`` of docs/editors.md's Neovim section."""
    page = (ROOT / "docs" / "editors.md").read_text("utf-8")
    found = re.search(r"^## Neovim\n.*?^```lua\n(.*?)^```", page, re.S | re.M)
    if found is None:
        raise Failed("docs/editors.md has no ```lua block under `## Neovim`")
    return found.group(1)


class Tmux:
    """One tmux server of our own (its own socket, no user configuration)."""

    def __init__(self, work: Path) -> None:
        self.socket = work / "tmux.sock"
        self.conf = work / "tmux.conf"
        self.conf.write_text("set -g status off\nset -g default-terminal tmux-256color\n")

    def run(self, *args: str) -> str:
        done = subprocess.run(["tmux", "-S", str(self.socket), "-f", str(self.conf), *args],
                              capture_output=True, text=True, timeout=TIMEOUT)
        if done.returncode != 0:
            raise Failed(f"tmux {args[0]}: {done.stderr.strip()}")
        return done.stdout

    def keys(self, *keys: str) -> None:
        self.run("send-keys", "-t", "nvim", *keys)

    def command(self, line: str) -> None:
        """An Ex command typed as a person types it."""
        self.keys("Escape")
        self.keys("-l", ":" + line)
        self.keys("Enter")

    def screen(self) -> str:
        return self.run("capture-pane", "-t", "nvim", "-e", "-p")

    def wait_for(self, text: str, what: str) -> str:
        """The screen once it shows ``text`` and stops changing."""
        deadline = time.monotonic() + TIMEOUT
        last = ""
        while time.monotonic() < deadline:
            screen = self.screen()
            if text in _plain(screen) and screen == last:
                return screen
            last = screen
            time.sleep(0.5)
        raise Failed(f"{what}: the screen never showed {text!r}; it showed:\n{_plain(last)}")

    def close(self) -> None:
        subprocess.run(["tmux", "-S", str(self.socket), "kill-server"], capture_output=True,
                       timeout=TIMEOUT)


def _plain(screen: str) -> str:
    return re.sub(r"\x1b\[[0-9;:]*m", "", screen)


def capture(work: Path) -> dict[str, str]:
    """The two screens, as tmux captured them (ANSI colours included)."""
    home = work / "home"
    (home / ".config" / "nvim").mkdir(parents=True)
    (home / ".config" / "nvim" / "init.lua").write_text(neovim_config() + _FLOAT_COLOURS, "utf-8")
    examples = work / "examples"
    for name in ("follow_colors", "lib"):
        shutil.copytree(ROOT / "examples" / name, examples / name)
    model = examples / "follow_colors" / "follow_colors.yaml"
    text = model.read_text("utf-8")
    wrong = text.replace("{name: landed, to: Done,", "{name: landed, to: Dnoe,")
    if wrong == text:
        raise Failed(f"{model.name} has no `landed` transition to `Done` to misspell")
    model.write_text(wrong, "utf-8")
    line = wrong[:wrong.index("to: Dnoe")].count("\n") + 1
    bin_dir = Path(sys.executable).parent
    if not (bin_dir / "hfsmc").exists():
        raise Failed(f"no hfsmc beside {sys.executable} (run `make setup`)")
    env = {"HOME": str(home), "PATH": f"{bin_dir}:/usr/bin:/bin", "TERM": "tmux-256color",
           "LANG": "C.UTF-8", "XDG_CONFIG_HOME": str(home / ".config"),
           "XDG_DATA_HOME": str(home / ".local/share"), "XDG_STATE_HOME": str(home / ".local/state"),
           "XDG_CACHE_HOME": str(home / ".cache"), "HFSMC_LSP_DEBOUNCE_MS": "150"}
    command = ["env", "-i", *(f"{k}={v}" for k, v in env.items()),
               "nvim", f"+{line}", "follow_colors/follow_colors.yaml"]
    tmux = Tmux(work)
    screens = {}
    try:
        tmux.run("new-session", "-d", "-s", "nvim", "-x", str(COLS), "-y", str(ROWS),
                 "-c", str(examples), *command)
        tmux.wait_for("unknown state `Dnoe`", "the diagnostic")
        tmux.command('call search("Dnoe")')
        tmux.command("lua vim.diagnostic.open_float()")
        screens["diagnostic"] = tmux.wait_for("did you mean", "the diagnostic's float")
        # Two windows: the top one on `Mission:` and its first reference, the bottom
        # one on the `link back` transition and the misspelt one; the search for the
        # new name, set beforehand, highlights what the rename changes.
        tmux.command("split")
        tmux.command(r'call search("^    LinkLost:") | normal! zt')
        tmux.command("wincmd k")
        tmux.command(r"call search('^  \zsMission:', 'w') | normal! zz")
        tmux.command(r"let @/ = '\<Flight\>' | set hlsearch")
        tmux.keys("F2")
        tmux.wait_for("New Name", "the rename's prompt")
        tmux.keys("C-u")
        tmux.keys("-l", "Flight")
        tmux.keys("Enter")
        screens["rename"] = tmux.wait_for("link back, to: Flight", "the rename")
    finally:
        tmux.close()
    return screens


def svg(screen: str, title: str) -> str:
    console = Console(record=True, width=COLS, file=io.StringIO(), color_system="truecolor",
                      force_terminal=True, legacy_windows=False)
    for row in _UNDERLINE_COLOUR.sub("", screen).rstrip("\n").split("\n"):
        console.print(Text.from_ansi(row, no_wrap=True), no_wrap=True, crop=True,
                      overflow="crop")
    console.print()  # a blank row below the last, so that its underscores are not clipped
    return console.export_svg(title=title, code_format=_SVG, font_aspect_ratio=0.602)


def photograph(svg_file: Path, png: Path, work: Path) -> None:
    """The SVG as chromium shows it, at its own size."""
    found = re.search(r'viewBox="0 0 ([\d.]+) ([\d.]+)"', svg_file.read_text("utf-8"))
    if found is None:
        raise Failed(f"{svg_file}: no viewBox")
    width, height = (round(float(n)) for n in found.groups())
    page = work / (svg_file.stem + ".html")
    page.write_text("<!doctype html><html><body style='margin:0;background:#fff'>"
                    f"<img src='{svg_file.name}' width='{width}' height='{height}'>"
                    "</body></html>", "utf-8")
    profile = Path(tempfile.mkdtemp(dir=work, prefix="chromium-"))
    done = subprocess.run(
        ["chromium", "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--hide-scrollbars", "--force-device-scale-factor=1", f"--user-data-dir={profile}",
         f"--window-size={width},{height}", f"--screenshot={png}", page.as_uri()],
        capture_output=True, text=True, timeout=120)
    if done.returncode != 0 or not png.exists():
        raise Failed(f"chromium did not photograph {svg_file.name}: {done.stderr.strip()[-400:]}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "editors",
                        help="where the PNGs go (default: docs/editors)")
    parser.add_argument("--keep", type=Path, help="keep the captures and SVGs in this folder")
    args = parser.parse_args(argv)
    missing = [tool for tool in ("nvim", "tmux", "chromium") if shutil.which(tool) is None]
    if missing:
        print(f"editor_screens: not installed: {', '.join(missing)} (Neovim is installed by "
              "hand: apt-get install neovim)", file=sys.stderr)
        return 1
    titles = {"diagnostic": "nvim follow_colors.yaml: a diagnostic of hfsmc lsp",
              "rename": "nvim follow_colors.yaml: Mission renamed Flight (<F2>)"}
    with tempfile.TemporaryDirectory(prefix="hfsmc-screens-") as tmp:
        work = Path(tmp)
        try:
            screens = capture(work)
            args.out.mkdir(parents=True, exist_ok=True)
            for name, screen in screens.items():
                (work / f"neovim-{name}.ans").write_text(screen, "utf-8")
                svg_file = work / f"neovim-{name}.svg"
                svg_file.write_text(svg(screen, titles[name]), "utf-8")
                photograph(svg_file, args.out / f"neovim-{name}.png", work)
                print(f"wrote {args.out / f'neovim-{name}.png'}")
        except (Failed, OSError, subprocess.TimeoutExpired) as error:
            print(f"editor_screens: {error}", file=sys.stderr)
            return 1
        finally:
            if args.keep is not None:
                args.keep.mkdir(parents=True, exist_ok=True)
                for kept in work.glob("neovim-*.*"):
                    shutil.copy2(kept, args.keep / kept.name)
    return 0


if __name__ == "__main__":
    sys.exit(main())
