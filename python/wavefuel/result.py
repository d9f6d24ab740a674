"""Reading a result file (docs/output.md, docs/corridors.md) with h5py: every dataset as a numpy array with its
units and description."""
import numpy as np


class Result(dict):
    """{"/group/name": numpy array} for every dataset of a result file (scalars as 0-d arrays, strings as str),
    with units[path] and description[path] from the datasets' attributes and attrs[path] every attribute of every
    group and dataset. Keys may be given without the leading "/"."""

    def __init__(self, path):
        super().__init__()
        import h5py  # only reading needs h5py
        self.path = path
        self.units, self.description, self.attrs = {}, {}, {}

        def attr(v):
            return v.decode() if isinstance(v, bytes) else v

        def visit(name, obj):
            full = "/" + name
            self.attrs[full] = {k: attr(v) for k, v in obj.attrs.items()}
            if not isinstance(obj, h5py.Dataset):
                return
            data = obj[()]
            if isinstance(data, bytes):
                data = data.decode()
            elif isinstance(data, np.ndarray) and data.dtype.kind in "OS":
                data = np.array([x.decode() if isinstance(x, bytes) else x for x in data.ravel()],
                                dtype=object).reshape(data.shape)
            dict.__setitem__(self, full, data)
            self.units[full] = attr(obj.attrs.get("units"))
            self.description[full] = attr(obj.attrs.get("description"))

        with h5py.File(path, "r") as f:
            self.attrs["/"] = {k: attr(v) for k, v in f.attrs.items()}
            f.visititems(visit)

    @staticmethod
    def _key(k):
        return k if k.startswith("/") else "/" + k

    def __getitem__(self, k):
        return dict.__getitem__(self, self._key(k))

    def __contains__(self, k):
        return dict.__contains__(self, self._key(k))

    def group(self, name):
        """The datasets under a group, by their names in it: result.group("summary")["fuel"]."""
        prefix = self._key(name).rstrip("/") + "/"
        return {k[len(prefix):]: v for k, v in self.items() if k.startswith(prefix) and "/" not in k[len(prefix):]}

    def __repr__(self):
        return f"<wavefuel.Result {self.path}: {len(self)} datasets>"


def read(path):
    """Read a wavefuel result file (`wavefuel run`, Simulation.run): a Result."""
    return Result(path)
