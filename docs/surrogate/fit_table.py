"""A `stampede fit --text` table as {column: array}, for the scripts of this folder."""
import numpy as np


def table(path):
    with open(path) as f:
        header = next(line for line in f if line.startswith("#") and " e1 " in f" {line[1:]} ")
    names = header[1:].split()
    data = np.loadtxt(path, comments="#")
    return {n: data[:, k] for k, n in enumerate(names)}
