// Joining tables by their rows' bytes; see table_join.hpp.
#include "io/table_join.hpp"

#include <algorithm>
#include <cstring>
#include <memory>

#include "io/durable_table.hpp"
#include "io/fits_error.hpp"

namespace stampede::io {
namespace {

constexpr long long kChunkRows = 4096;

// An open table HDU, closed on every path out.
class OpenTable {
 public:
  OpenTable(const std::string& path, const std::string& extname) : path_(path) {
    int status = 0;
    fits_open_diskfile(&f_, path.c_str(), READONLY, &status);
    if (status != 0) {
      f_ = nullptr;
      throw FitsError(path + ": cannot open it: " + cfitsio_status_text(status));
    }
    fits_movnam_hdu(f_, BINARY_TBL, const_cast<char*>(extname.c_str()), 0, &status);
    fits_get_num_rowsll(f_, &rows_, &status);
    fits_read_key(f_, TLONG, "NAXIS1", &row_bytes_, nullptr, &status);
    if (status != 0) throw FitsError(path + ": no readable " + extname + " table: " + cfitsio_status_text(status));
  }
  ~OpenTable() {
    int status = 0;
    if (f_) fits_close_file(f_, &status);
    if (status) fits_clear_errmsg();
  }
  OpenTable(const OpenTable&) = delete;
  OpenTable& operator=(const OpenTable&) = delete;
  fitsfile* get() const { return f_; }
  long long rows() const { return rows_; }
  long row_bytes() const { return row_bytes_; }
  const std::string& path() const { return path_; }

  // A string key's value, "" when absent.
  std::string key(const std::string& name) const {
    char value[FLEN_VALUE] = {};
    int status = 0;
    fits_read_key(f_, TSTRING, name.c_str(), value, nullptr, &status);
    if (status != 0) {
      fits_clear_errmsg();
      return "";
    }
    return value;
  }
  double number(const std::string& name) const {
    double v = 0;
    int status = 0;
    fits_read_key(f_, TDOUBLE, name.c_str(), &v, nullptr, &status);
    if (status != 0) fits_clear_errmsg();
    return status == 0 ? v : 0;
  }

  // The columns as the durable table makes them (an unsigned 32-bit column is J with TZERO 2^31:
  // made as V, it is made the same).
  std::vector<TableColumn> columns() const {
    int n = 0, status = 0;
    fits_get_num_cols(f_, &n, &status);
    std::vector<TableColumn> out;
    for (int i = 1; i <= n; ++i) {
      const std::string k = std::to_string(i);
      TableColumn c{key("TTYPE" + k), key("TFORM" + k), key("TUNIT" + k), key("TCOMM" + k)};
      if (c.tform == "1J" && number("TZERO" + k) == 2147483648.0) c.tform = "1V";
      out.push_back(std::move(c));
    }
    return out;
  }

  // Every header record but the table's structure, its columns' and the keys in `dropped`, in
  // order (a dropped key's CONTINUE cards too).
  std::vector<std::string> records(const std::vector<std::string>& dropped) const {
    int count = 0, more = 0, status = 0;
    fits_get_hdrspace(f_, &count, &more, &status);
    std::vector<std::string> out;
    bool dropping = false;
    for (int i = 1; i <= count; ++i) {
      char card[FLEN_CARD] = {};
      fits_read_record(f_, i, card, &status);
      if (status != 0) throw FitsError(path_ + ": cannot read header record " + std::to_string(i));
      const std::string record = card;
      std::string name = record.substr(0, std::min<std::size_t>(8, record.size()));
      while (!name.empty() && name.back() == ' ') name.pop_back();
      if (name == "HIERARCH") {
        const std::size_t eq = record.find('=');
        name = record.substr(9, eq == std::string::npos ? std::string::npos : eq - 9);
        while (!name.empty() && name.back() == ' ') name.pop_back();
      }
      if (name == "CONTINUE") {
        if (!dropping) out.push_back(record);
        continue;
      }
      dropping = is_table_structure_key(name) || std::find(dropped.begin(), dropped.end(), name) != dropped.end();
      if (!dropping && record.find_first_not_of(' ') != std::string::npos) out.push_back(record);
    }
    return out;
  }

 private:
  std::string path_;
  fitsfile* f_ = nullptr;
  long long rows_ = 0;
  long row_bytes_ = 0;
};

}  // namespace

bool is_table_structure_key(const std::string& key) {
  for (const char* k : {"XTENSION", "BITPIX", "NAXIS", "NAXIS1", "NAXIS2", "PCOUNT", "GCOUNT", "TFIELDS", "EXTNAME"})
    if (key == k) return true;
  for (const char* prefix : {"TTYPE", "TFORM", "TUNIT", "TCOMM", "TZERO", "TSCAL"})
    if (key.starts_with(prefix) && key.size() > std::strlen(prefix) &&
        key.find_first_not_of("0123456789", std::strlen(prefix)) == std::string::npos)
      return true;
  return false;
}

long long join_tables(const TableJoinOptions& o) {
  if (o.tables.empty()) throw CatalogError("no tables to join");
  std::vector<TableColumn> columns;
  DurableTableOptions t;
  long long total = 0;
  {
    const OpenTable first(o.tables.front(), o.extname);
    columns = first.columns();
    const std::vector<std::string> records = first.records(o.dropped_keys);
    t.describe = [records](fitsfile* f, int* status) {
      for (const std::string& r : records) fits_write_record(f, r.c_str(), status);
    };
  }
  for (const std::string& path : o.tables) {
    const OpenTable table(path, o.extname);
    const std::vector<TableColumn> mine = table.columns();
    const bool same = mine.size() == columns.size() &&
                      std::equal(mine.begin(), mine.end(), columns.begin(), [](const TableColumn& a, const TableColumn& b) {
                        return a.name == b.name && a.tform == b.tform;
                      });
    if (!same) throw CatalogError(path + " has other columns than " + o.tables.front());
    total += table.rows();
  }
  t.path = o.output;
  t.extname = o.extname;
  t.columns = columns;
  t.fingerprint = "stampede merge of " + std::to_string(o.tables.size()) + " tables\n";
  t.layout = "joined " + o.extname;
  t.reserved_keys = static_cast<int>(o.final_keys.size());
  t.keep_on_write_failure = false;  // a join has no resume: a failed one is redone whole
  std::unique_ptr<DurableTable> out = DurableTable::create(t);
  long long written = 0;
  try {
    std::vector<unsigned char> bytes;
    for (const std::string& path : o.tables) {
      const OpenTable table(path, o.extname);
      for (long long first = 0; first < table.rows(); first += kChunkRows) {
        const long long n = std::min(kChunkRows, table.rows() - first);
        bytes.resize(static_cast<std::size_t>(n * table.row_bytes()));
        int status = 0;
        fits_read_tblbytes(table.get(), first + 1, 1, static_cast<LONGLONG>(bytes.size()), bytes.data(), &status);
        if (status != 0) throw FitsError(path + ": cannot read rows: " + cfitsio_status_text(status));
        out->append(n, n, [&] {
          int write_status = 0;
          errno = 0;
          fits_write_tblbytes(out->fits(), out->rows() + 1, 1, static_cast<LONGLONG>(bytes.size()), bytes.data(),
                              &write_status);
          out->check(write_status, "write rows to", errno);
        });
        written += n;
        if (o.on_progress) o.on_progress(written, total);
      }
    }
    out->finish(o.final_keys);
  } catch (...) {
    out->abandon();
    throw;
  }
  return written;
}

}  // namespace stampede::io
