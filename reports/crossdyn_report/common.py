"""Small helpers shared by the report and the scene pictures: atomic writes, compact PNGs, number
formats, the runs' CSV files and the look of each run."""

import io
import os
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)
import numpy as np  # noqa: E402

DPI = 96


def write_atomic(path, data):
    """Writes bytes or text to path through a new temporary file in the same folder and a rename,
    so a reader sees the old file or the complete new one."""
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=os.path.basename(path) + ".tmp.", dir=folder)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data if isinstance(data, bytes) else data.encode("utf-8"))
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def png_bytes(fig, colours=256):
    """A figure as a palette PNG (a third of the size of a full-colour one, which matters for the
    committed example); matplotlib's own PNG when Pillow is missing."""
    try:
        from PIL import Image  # Pillow comes with Debian's matplotlib
    except ImportError:
        Image = None
    buf = io.BytesIO()
    if Image is not None:
        # The raw RGBA pixels that savefig would encode as PNG: the same drawing (same dpi, colours
        # and layout) without a zlib pass whose output would be decoded again at once. The size is
        # Agg's canvas size at DPI (int of the figure's size in pixels, as FigureCanvasAgg).
        fig.savefig(buf, format="rgba", dpi=DPI)
        width, height = (int(v * DPI) for v in fig.get_size_inches())
        raw = buf.getvalue()
        if len(raw) == 4 * width * height:
            plt.close(fig)
            try:
                image = Image.frombuffer("RGBA", (width, height), raw, "raw", "RGBA", 0, 1)
                return _palette_png(image, colours)
            except Exception:  # an old Pillow: matplotlib's own PNG
                out = io.BytesIO()
                plt.imsave(out, np.frombuffer(raw, np.uint8).reshape(height, width, 4), format="png")
                return out.getvalue()
        buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    plt.close(fig)
    try:
        buf.seek(0)
        return _palette_png(Image.open(buf), colours)
    except Exception:  # no Pillow or an old one
        return buf.getvalue()


def _palette_png(image, colours):
    from PIL import Image

    image = image.convert("RGB").quantize(colors=colours, method=Image.Quantize.MEDIANCUT)
    out = io.BytesIO()
    image.save(out, format="PNG", optimize=True)
    return out.getvalue()


def save_figure(fig, path, colours=256):
    write_atomic(path, png_bytes(fig, colours))


def warn(message):
    print("make_report.py: " + message, file=sys.stderr)


def sci(v, digits=3):
    if v is None:
        return "n/a"
    if v == 0:
        return "0"
    return "%.*e" % (digits - 1, v)


def gfmt(v, digits=6):
    return "n/a" if v is None else "%.*g" % (digits, v)


def vec(v, digits=6):
    return "(" + ", ".join(gfmt(x, digits) for x in v) + ")"


# One look per run, the same on every page: the analytic solution is a thick light line under the
# engines; engines differ in colour and dash so that curves lying on top of each other stay visible.
STYLES = {
    "analytic": dict(color="0.55", linestyle="-", linewidth=4.0, alpha=0.8),
    "kane": dict(color="tab:blue", linestyle="-", linewidth=2.2),
    "lagrange": dict(color="tab:orange", linestyle="--", linewidth=1.8),
    "newton-euler": dict(color="tab:green", linestyle=":", linewidth=2.0),
}
EXTRA_COLOURS = ["tab:red", "tab:purple", "tab:brown", "tab:pink", "tab:olive", "tab:cyan"]
# Line styles by engine where colour means something else (the joints chart: colour = joint).
DASHES = {"analytic": "-", "kane": "-", "lagrange": "--", "newton-euler": ":"}
EXTRA_DASHES = ["-.", (0, (5, 1, 1, 1, 1, 1)), (0, (1, 2)), (0, (8, 2))]


def style_of(label, index):
    if label in STYLES:
        return dict(STYLES[label])
    base = label.split("*")[0]
    colour = EXTRA_COLOURS[index % len(EXTRA_COLOURS)]
    return dict(STYLES.get(base, {}), color=colour, linestyle="-.", linewidth=1.6)


def dash_of(label, index):
    if label in DASHES:
        return DASHES[label]
    return EXTRA_DASHES[index % len(EXTRA_DASHES)]


def load_csv(path):
    """Returns (columns, data) with data shaped rows x columns, or None when unreadable."""
    try:
        with open(path, encoding="utf-8") as f:
            header = f.readline().strip().split(",")
        data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    except (OSError, ValueError) as e:
        warn("cannot read %s: %s" % (path, e))
        return None
    if data.size == 0:
        data = np.zeros((0, len(header)))
    return header, data


class Run:
    """One run of a scene with its samples."""

    def __init__(self, info, out_dir, index):
        self.label = info["label"]
        self.info = info
        self.index = index
        self.style = style_of(self.label, index)
        self.dash = dash_of(self.label, index)
        self.columns, self.data = [], np.zeros((0, 0))
        if info.get("data"):
            loaded = load_csv(os.path.join(out_dir, info["data"]))
            if loaded:
                self.columns, self.data = loaded

    def has(self, name):
        return name in self.columns and self.data.shape[0] > 0

    def col(self, name):
        return self.data[:, self.columns.index(name)]

    @property
    def t(self):
        return self.col("t")
