"""The report's view of FITS files: headers, tables read in row chunks, images. Every byte is read
by the C++ io layer through the stampede module (fits_hdus, fits_header, read_table, read_image);
this file only shapes their answers for the report. A file that cannot be read is a
stampede.FitsError naming the file and HDU (and column).

Compressed files are refused: CFITSIO decompresses a whole .gz file in memory on every open, and
read_table opens the file once per chunk, so a large table would cost its size in memory per chunk.
"""

import stampede


def where(path, hdu):
    """"PATH[HDU n 'NAME']", as the io layer's messages name an HDU."""
    return f"{path}[HDU {hdu['index']}" + (f" '{hdu['name']}']" if hdu["name"] else "]")


class Header:
    """The cards of one HDU: values by keyword (HIERARCH keywords by their long name; a repeated
    keyword's last value), COMMENT lines, and the keywords in card order."""

    def __init__(self, cards):
        self.values, self.comments, self.order = {}, [], []
        for key, value, _ in cards:
            if key == "COMMENT":
                self.comments.append(value)
            elif key in ("HISTORY", ""):
                continue
            else:
                if key not in self.values:
                    self.order.append(key)
                self.values[key] = value

    def get(self, key, default=None):
        return self.values.get(key, default)

    def __contains__(self, key):
        return key in self.values

    def __getitem__(self, key):
        return self.values[key]


class FitsFile:
    """The HDUs of a FITS file (fits_hdus' dicts); headers and data are read on demand."""

    def __init__(self, path):
        self.path = str(path)
        if self.path.endswith((".gz", ".fz", ".bz2")):
            raise stampede.FitsError(f"{self.path}: compressed FITS is not read by the report; decompress it first")
        self.hdus = stampede.fits_hdus(self.path)

    def header(self, index):
        return Header(stampede.fits_header(self.path, index))

    def hdu(self, name):
        """The first HDU with EXTNAME `name`, or None."""
        return next((h for h in self.hdus if h["name"] == name), None)

    def table(self, name):
        """The table HDU `name` as a Table, or None when the file has no such HDU."""
        h = self.hdu(name)
        return None if h is None else Table(self, h)

    def image(self, hdu):
        """An image HDU's pixels as a 2-D float64 array [y, x]."""
        return stampede.read_image(self.path, hdu=hdu["index"])


class Table:
    """A table HDU: its header, column names and rows, its columns read in row ranges."""

    def __init__(self, fits, hdu):
        self.path, self.index = fits.path, hdu["index"]
        self.where = where(fits.path, hdu)
        if hdu["kind"] != "table":
            raise stampede.FitsError(f"{self.where}: not a table (it is an {hdu['kind']} HDU)")
        self.header = fits.header(self.index)
        self.rows, self.columns = hdu["rows"], hdu["columns"]

    def has(self, name):
        return name in self.columns

    def read(self, names, start=0, stop=None):
        """Rows [start, stop) (clipped to the table) of the named columns as a dict of arrays:
        int64 for integer columns (TZERO applied), float64 for real ones."""
        stop = self.rows if stop is None else min(stop, self.rows)
        start = min(start, stop)
        return stampede.read_table(self.path, self.index, list(names), first_row=start, count=stop - start)

    def chunks(self, names, chunk_rows):
        """(start, columns) for consecutive row ranges of at most chunk_rows rows."""
        for start in range(0, self.rows, chunk_rows):
            yield start, self.read(names, start, start + chunk_rows)
