"""Memoised source lookups for Taichi's Python frontend (docs/design-notes.md, "Compile time").

Taichi turns a kernel into IR from its Python source each time it specialises one, and every
@ti.func once per call site. On each such pass it reads the function's source again
(`inspect.getsourcelines`, which tokenises the file from the top) and, for every node of the
function's syntax tree, formats a position message: the file, the line, and the source line
with a caret under the node, run through `textwrap` to 80 columns. The message becomes the
node's debug information, shown only if compiling or an assertion fails. Both are functions of
the function's source and the node's place in it alone, yet the impulse pair solver's first
substep made 94,573 such messages and 2,047 source reads: together about 60 % of the time
Taichi spent turning its kernels into IR (the part of a first launch that Taichi's offline
cache of compiled kernels does not skip).

It also runs every source line through `textwrap.fill` and the function through
`textwrap.dedent` at each call site: pure functions of the text, memoised likewise.

A message is new the first time in a process (the memo lives as long as the process), and
making it ran each quoted line and its caret line through a `textwrap.TextWrapper(width=80)`:
about a quarter of the frontend's time for the default demo's kernel, in every process, with
Taichi's offline cache warm or not. A line that fits is its own wrapping, less trailing spaces;
`LineWrapper` returns that at once for such lines (printable ASCII, at most the width once
trailing spaces go) and leaves every other line to TextWrapper: the same strings.

`install()` memoises these in Taichi's own modules (it replaces the module attributes its
frontend calls; nothing else changes): the same strings, made once per source position. It
does so only for the Taichi versions it was written against (1.7), whose frontend it has
checked; anywhere else it leaves Taichi alone. TAI_COLL_FRONTEND_CACHE=0 leaves it off.
"""

import functools
import os

import taichi as ti

#: The Taichi versions whose frontend these memos were written against (major, minor).
CHECKED_VERSIONS = {(1, 7)}

#: Position messages kept before the memo starts again (each about 200-400 characters).
MAX_MESSAGES = 200_000


def taichi_version() -> tuple:
    """(major, minor) of the Taichi imported (ti.__version__ is a tuple of ints in 1.7)."""
    version = ti.__version__
    if isinstance(version, str):
        version = tuple(int(part) for part in version.split(".")[:2] if part.isdigit())
    return tuple(version[:2])


def may_patch(variable: str) -> bool:
    """Whether tai_coll may change Taichi's Python frontend: a Taichi version it was checked
    against, and the environment variable `variable` not set to 0 (it turns the change off)."""
    return os.environ.get(variable, "1") != "0" and taichi_version() in CHECKED_VERSIONS


def patch_once(variable: str):
    """Make `apply`, a function that changes Taichi and returns whether it could (False:
    Taichi lacks what it changes), an install function: it applies once, only if
    may_patch(variable), returns whether the change is on, and is safe to call again. Whether
    it is on stays readable as `install.installed`. (frontend_cache, serial_loops and
    fast_launch install their changes so.)"""
    def decorate(apply):
        @functools.wraps(apply)
        def install() -> bool:
            if not install.installed:
                install.installed = may_patch(variable) and apply()
            return install.installed

        install.installed = False
        return install
    return decorate


def line_wrapper(base):
    """A TextWrapper class (`base`, textwrap's) whose wrap() returns a line that fits as it is:
    for printable ASCII text with TextWrapper's default options, no longer than the width once
    trailing spaces are dropped, TextWrapper's own result is [text.rstrip(" ")], or [] for
    spaces alone (one line: no chunk is moved or dropped but the trailing spaces). A longer
    such line, wrapped by a TextWrapper with only its width set, is wrapped once and its lines
    kept. Anything else goes to TextWrapper."""

    longer = {}  # width -> {a longer line: its wrapping} (a line is quoted for each node on it)

    @functools.cache
    def defaults(width):
        return vars(base(width=width))

    class LineWrapper(base):
        def wrap(self, text):
            if (text.isascii() and text.isprintable() and self.drop_whitespace and self.max_lines is None
                    and not self.initial_indent):
                kept = text.rstrip(" ")
                if len(kept) <= self.width:
                    return [kept] if kept else []
                if vars(self) == defaults(self.width):  # (TextWrapper's other options as it made them)
                    known = longer.setdefault(self.width, {})
                    if text not in known:
                        if len(known) >= MAX_MESSAGES:
                            known.clear()
                        known[text] = super().wrap(text)
                    return list(known[text])
            return super().wrap(text)

    return LineWrapper


@patch_once("TAI_COLL_FRONTEND_CACHE")
def install() -> bool:
    """Memoise Taichi's source reads and position messages; returns whether they are on
    (False: another Taichi version, or TAI_COLL_FRONTEND_CACHE=0). Safe to call again."""
    try:
        from taichi.lang import kernel_impl
        from taichi.lang.ast import ast_transformer_utils
        context = ast_transformer_utils.ASTTransformerContext
        originals = (kernel_impl.getsourcelines, kernel_impl.getsourcefile, context.get_pos_info)
        wrap = kernel_impl.textwrap
        wrapper = ast_transformer_utils.TextWrapper  # (what get_pos_info wraps each quoted line with)
    except (ImportError, AttributeError):
        return False
    read_lines, read_file, position = originals
    # a function's source lines, first line's number and file do not change while the process
    # runs (Taichi reads them for every specialisation and call site)
    lines_of = functools.cache(read_lines)
    messages = {}

    def getsourcelines(func):
        lines, start = lines_of(func)
        return list(lines), start  # (a list of its own for each caller, as before)

    def get_pos_info(self, node):
        # the function's code (a redefinition has other code), file, line offset (which
        # Taichi may take from the call site), indent and name fix the source lines the
        # message quotes and its header; the node's type and span fix the rest of it
        func = self.func.func
        key = (getattr(func, "__code__", None), self.file, self.lineno_offset, self.indent, func.__name__,
               type(node), node.lineno, getattr(node, "end_lineno", None), node.col_offset,
               getattr(node, "end_col_offset", None))
        message = messages.get(key)
        if message is None:
            if len(messages) >= MAX_MESSAGES:
                messages.clear()
            message = messages[key] = position(self, node)
        return message

    class SourceText:
        """What Taichi's frontend uses of `textwrap`, memoised: it runs every source line of
        a function through `fill` (tabs expanded), and then `dedent`, at every call site."""
        fill = staticmethod(functools.lru_cache(maxsize=MAX_MESSAGES)(wrap.fill))
        dedent = staticmethod(functools.lru_cache(maxsize=4096)(wrap.dedent))

        def __getattr__(self, name):
            return getattr(wrap, name)

    kernel_impl.textwrap = SourceText()
    ast_transformer_utils.TextWrapper = line_wrapper(wrapper)
    kernel_impl.getsourcelines = getsourcelines
    kernel_impl.getsourcefile = functools.cache(read_file)
    context.get_pos_info = get_pos_info
    return True
