// FitsFile implementation: every non-zero CFITSIO status becomes a FitsError naming the file and
// HDU (see fits_file.hpp).
#include "io/fits_file.hpp"

#include <fitsio.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <climits>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string_view>
#include <system_error>
#include <utility>

#include "io/fits_header_guard.hpp"

namespace stampede::io {
namespace {

fitsfile* as_fits(void* p) { return static_cast<fitsfile*>(p); }

// The file part of a CFITSIO path ("a.fits[CASES]" -> "a.fits", "!a.fits" -> "a.fits"), so error
// messages name the file as it is on disk. Falls back to the path itself.
// A name CFITSIO may take for a URL or a driver ("http://", "ftp:20", "mem://", "stdin"): a scheme,
// letters before a ':', "://" anywhere, or a leading '~' (a local file of such a name is given as
// ./NAME; the shell expands an unquoted ~). stampede identifies a run by
// its files' bytes, so it reads and writes files on disk only; CFITSIO would try the network (and
// hang), or leak in its parse of an unknown scheme.
bool is_url(const std::string& name) {
  // Control characters (a tab, a newline) are in no file's name here, and CFITSIO parses names
  // with them in its own way (fuzz finding F20: tabs, then "file://", leaked in its URL parse).
  if (std::any_of(name.begin(), name.end(), [](char c) { return static_cast<unsigned char>(c) < 0x20; })) return true;
  // CFITSIO skips leading blanks before it parses a name (fuzz finding F16: " ~user/x.fits").
  const std::size_t first = name.find_first_not_of(' ');
  const std::string path = first == std::string::npos ? std::string() : name.substr(first);
  // A file:// name is a file, but CFITSIO expands a '~' after the prefix too (fuzz finding F17:
  // "file://~E"), and splits at a second "://".
  if (path.starts_with("file://")) {
    const std::size_t rest = path.find_first_not_of(' ', 7);
    return rest == std::string::npos || path[rest] == '~' || path.find("://", 7) != std::string::npos;
  }
  if (path == "stdin" || path == "stdout" || path == "-") return true;
  if (path.starts_with('~')) return true;  // CFITSIO's own home-directory expansion crashes on an unknown user
  if (path.find("://") != std::string::npos) return true;  // CFITSIO splits a URL there, wherever it is
  std::size_t k = 0;
  while (k < path.size() && (std::isalnum(static_cast<unsigned char>(path[k])) || path[k] == '+' || path[k] == '.' ||
                             path[k] == '-'))
    ++k;
  return k > 0 && k < path.size() && path[k] == ':' && std::isalpha(static_cast<unsigned char>(path[0]));
}

// CFITSIO reads "in.fits(out.fits)" as "copy in.fits to out.fits and open the copy": a read that
// writes a file (and "(~user)" reaches its home-directory expansion). A '(' before any '[' is that
// syntax to CFITSIO; such a name is refused.
bool has_copy_syntax(const std::string& path) {
  const std::size_t bracket = path.find('[');
  return path.find('(') < bracket;
}

// CFITSIO's filters after a name ("[bin x=1:1e9]" allocates the histogram it describes, "[e1>0]"
// keeps some rows, "[col ...]" computes columns): a read of other bytes than the file's. Only an
// HDU is selected by brackets here: "[2]", "[EXTNAME]" or "[EXTNAME,VERSION]", once, at the end.
bool has_filter_syntax(const std::string& path) {
  const std::size_t open = path.find('[');
  if (open == std::string::npos) return false;
  if (path.back() != ']' || path.find('[', open + 1) != std::string::npos) return true;
  // An HDU number, or an EXTNAME (a letter, then letters, digits and '_') with an optional
  // ",VERSION": anything else CFITSIO parses as an expression (fuzz finding F18: "[-f-.te.]"
  // leaked in its parser).
  const std::string spec = path.substr(open + 1, path.size() - open - 2);
  const auto is_digit = [](char c) { return std::isdigit(static_cast<unsigned char>(c)) != 0; };
  if (!spec.empty() && std::all_of(spec.begin(), spec.end(), is_digit)) return false;
  const std::size_t comma = spec.find(',');
  const std::string name = spec.substr(0, comma), version = comma == std::string::npos ? "" : spec.substr(comma + 1);
  if (name.empty() || !std::isalpha(static_cast<unsigned char>(name[0]))) return true;
  for (const char c : name)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_') return true;
  if (comma != std::string::npos && (version.empty() || !std::all_of(version.begin(), version.end(), is_digit)))
    return true;
  return false;
}

std::string root_name(const std::string& path) {
  if (path.empty() || path.size() >= FLEN_FILENAME || is_url(path)) return path;  // ffrtnm's buffers are fixed
  std::string url = path;  // ffrtnm takes a non-const char*
  char root[FLEN_FILENAME] = {};
  int status = 0;
  fits_parse_rootname(url.data(), root, &status);
  if (status != 0 || root[0] == '\0') {
    fits_clear_errmsg();
    return path;
  }
  return root;
}

bool iequals(std::string_view a, std::string_view b) {
  return std::ranges::equal(a, b, [](unsigned char x, unsigned char y) {
    return std::toupper(x) == std::toupper(y);
  });
}

// Moves back to 1-based HDU `hdunum` after a failed move, so a caught FitsError leaves the file
// where it was; CFITSIO may have stopped part-way.
void restore_hdu(fitsfile* f, int hdunum) {
  int status = 0;
  fits_movabs_hdu(f, hdunum, nullptr, &status);
  if (status != 0) fits_clear_errmsg();
}

bool is_numeric_column_type(int type) {
  switch (type) {
    case TBYTE: case TSBYTE: case TSHORT: case TUSHORT: case TINT: case TUINT:
    case TLONG: case TULONG: case TLONGLONG: case TULONGLONG: case TFLOAT: case TDOUBLE:
      return true;
    default:
      return false;  // strings, logicals, bits, complex
  }
}

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Whether a failed open (CFITSIO `status`) is of a file that is not FITS at all, which CFITSIO's
// text ("1st key not SIMPLE or XTENSION") does not say to a reader who gave the wrong file: a
// plain file on disk whose first card is not SIMPLE (gzip files are left to CFITSIO's text).
bool not_fits(int status, const std::string& path) {
  if (status != NO_SIMPLE && status != UNKNOWN_REC) return false;
  std::ifstream in(root_name(path), std::ios::binary);
  char head[9] = {};
  if (!in.read(head, sizeof head)) return false;
  const std::string_view start(head, sizeof head);
  return start != "SIMPLE  =" && !start.starts_with("\x1f\x8b");
}

}  // namespace

std::string fits_root_name(const std::string& path) { return root_name(path); }

// --- lifetime -------------------------------------------------------------------------------------

FitsFile::FitsFile(void* fptr, std::string path, bool auto_image)
    : fptr_(fptr), path_(std::move(path)), root_(root_name(path_)), auto_image_(auto_image) {}

FitsFile FitsFile::open_read(const std::string& path) {
  if (is_url(path)) throw FitsError("cannot open FITS file '" + path + "': a URL, a device or a name with control characters, not a file on disk (a local file of this name: ./NAME)");
  if (has_copy_syntax(path))
    throw FitsError("cannot open FITS file '" + path + "': '(' in a name is CFITSIO's input(output) copy, which would "
                    "write a file; rename the file");
  if (has_filter_syntax(path))
    throw FitsError("cannot open FITS file '" + path + "': brackets select an HDU only ([2], [EXTNAME] or "
                    "[EXTNAME,VERSION], at the end); CFITSIO's row filters, binning and column expressions are not "
                    "read");
  // Only a file on disk reaches CFITSIO's parse of its name (each of fuzz findings F16 to F20 was a
  // name of no file that CFITSIO's parser mishandled).
  {
    const std::size_t from = path.find_first_not_of(' ');
    std::string file = from == std::string::npos ? std::string() : path.substr(from);
    if (file.starts_with("file://")) file = file.substr(7);
    if (const std::size_t bracket = file.find('['); bracket != std::string::npos) file.resize(bracket);
    std::error_code ec;
    if (!std::filesystem::is_regular_file(file, ec))
      throw FitsError("cannot open FITS file '" + path + "': no such file" +
                      (std::filesystem::exists(file, ec) ? " (it is not a regular file)" : ""));
  }
  check_fits_headers(fits_root_name(path));  // before CFITSIO parses what would crash it
  fitsfile* f = nullptr;
  int status = 0;
  fits_open_file(&f, path.c_str(), READONLY, &status);
  if (status != 0) {
    // CFITSIO frees the half-opened file itself on failure.
    throw FitsError("cannot open FITS file '" + path + "': " + (not_fits(status, path) ? "not a FITS file: " : "") +
                    cfitsio_status_text(status));
  }
  return FitsFile(f, path, /*auto_image=*/true);
}

FitsFile FitsFile::create(const std::string& path, bool overwrite) {
  // CFITSIO's "!" prefix means "replace an existing file".
  const std::string name = (overwrite && !path.starts_with('!')) ? "!" + path : path;
  if (is_url(path))
    throw FitsError("cannot create FITS file '" + path + "': a URL, a device or a name with control characters, not a file on disk (a local file of this name: ./NAME)");
  if (has_copy_syntax(path))
    throw FitsError("cannot create FITS file '" + path + "': '(' in a name is CFITSIO's input(output) syntax; rename the file");
  fitsfile* f = nullptr;
  int status = 0;
  fits_create_file(&f, name.c_str(), &status);
  if (status != 0) {
    std::string msg = "cannot create FITS file '" + path + "': " + cfitsio_status_text(status);
    std::error_code ec;
    if (!overwrite && std::filesystem::exists(root_name(path), ec)) {
      msg += " (the file exists and overwrite is false)";
    }
    throw FitsError(msg);
  }
  return FitsFile(f, path, /*auto_image=*/false);
}

FitsFile::FitsFile(FitsFile&& other) noexcept
    : fptr_(std::exchange(other.fptr_, nullptr)),
      path_(std::move(other.path_)),
      root_(std::move(other.root_)),
      auto_image_(other.auto_image_) {}

FitsFile& FitsFile::operator=(FitsFile&& other) noexcept {
  if (this != &other) {
    close_noexcept();
    fptr_ = std::exchange(other.fptr_, nullptr);
    path_ = std::move(other.path_);
    root_ = std::move(other.root_);
    auto_image_ = other.auto_image_;
  }
  return *this;
}

FitsFile::~FitsFile() { close_noexcept(); }

void FitsFile::close_noexcept() noexcept {
  if (fptr_ == nullptr) return;
  int status = 0;
  fits_close_file(as_fits(std::exchange(fptr_, nullptr)), &status);  // frees even on error
  if (status != 0) fits_clear_errmsg();
}

void FitsFile::close() {
  if (fptr_ == nullptr) return;
  int status = 0;
  fits_close_file(as_fits(std::exchange(fptr_, nullptr)), &status);
  if (status != 0) {
    throw FitsError("cannot close FITS file '" + path_ + "': " + cfitsio_status_text(status));
  }
}

const std::string& FitsFile::path() const { return path_; }

void* FitsFile::handle() {
  if (fptr_ == nullptr) {
    throw FitsError(path_.empty() ? std::string("FitsFile was moved from or closed")
                                  : "FITS file '" + path_ + "' is closed");
  }
  return fptr_;
}

// --- error reporting ------------------------------------------------------------------------------

std::string FitsFile::describe() {
  if (fptr_ == nullptr) return root_ + "[closed]";
  fitsfile* f = as_fits(fptr_);
  int hdunum = 1;
  fits_get_hdu_num(f, &hdunum);
  std::string out = root_ + "[HDU " + std::to_string(hdunum - 1);
  char extname[FLEN_VALUE] = {};
  int status = 0;
  fits_read_key(f, TSTRING, "EXTNAME", extname, nullptr, &status);
  if (status == 0 && extname[0] != '\0') {
    out += " '" + std::string(extname) + "'";
  } else if (status != 0) {
    fits_clear_errmsg();  // no EXTNAME is normal (e.g. the primary HDU)
  }
  return out + "]";
}

void FitsFile::fail(const std::string& what) { throw FitsError(describe() + ": " + what); }

void FitsFile::fail_status(int status, const std::string& what) {
  const std::string text = cfitsio_status_text(status);  // before describe(), which touches CFITSIO again
  fail(what + ": " + text);
}

// --- HDU navigation -------------------------------------------------------------------------------

int FitsFile::hdu_count() {
  int n = 0;
  int status = 0;
  fits_get_num_hdus(as_fits(handle()), &n, &status);
  if (status != 0) fail_status(status, "cannot count HDUs");
  return n;
}

void FitsFile::move_to(int hdu_index) {
  fitsfile* f = as_fits(handle());
  if (hdu_index < 0 || hdu_index == INT_MAX) {
    fail("no HDU " + std::to_string(hdu_index) + " (HDU indices start at 0)");
  }
  int before = 1;
  fits_get_hdu_num(f, &before);
  int status = 0;
  fits_movabs_hdu(f, hdu_index + 1, nullptr, &status);
  if (status != 0) {
    const std::string text = cfitsio_status_text(status);
    restore_hdu(f, before);
    fail("cannot move to HDU " + std::to_string(hdu_index) + ": " + text);
  }
  auto_image_ = false;
}

void FitsFile::move_to(const std::string& extname) {
  if (!move_to_if_present(extname)) fail("no HDU with EXTNAME '" + extname + "'");
}

bool FitsFile::move_to_if_present(const std::string& extname) {
  fitsfile* f = as_fits(handle());
  int before = 1;
  fits_get_hdu_num(f, &before);
  std::string name = extname;
  int status = 0;
  fits_movnam_hdu(f, ANY_HDU, name.data(), 0, &status);
  if (status == 0) {
    auto_image_ = false;
    return true;
  }
  const std::string text = cfitsio_status_text(status);
  restore_hdu(f, before);
  if (status == BAD_HDU_NUM) return false;
  fail("cannot move to HDU '" + extname + "': " + text);
}

int FitsFile::hdu_index() {
  int hdunum = 1;
  fits_get_hdu_num(as_fits(handle()), &hdunum);
  return hdunum - 1;
}

FitsFile::HduKind FitsFile::hdu_kind() {
  fitsfile* f = as_fits(handle());
  int type = 0, naxis = 0, status = 0;
  fits_get_hdu_type(f, &type, &status);
  if (status != 0) fail_status(status, "cannot read HDU type");
  if (type != IMAGE_HDU) return HduKind::kTable;
  fits_get_img_dim(f, &naxis, &status);
  if (status != 0) fail_status(status, "cannot read NAXIS");
  if (naxis <= 0) return HduKind::kEmpty;
  std::vector<LONGLONG> dims(static_cast<std::size_t>(naxis));
  fits_get_img_sizell(f, naxis, dims.data(), &status);
  if (status != 0) fail_status(status, "cannot read image size");
  return std::ranges::all_of(dims, [](LONGLONG d) { return d > 0; }) ? HduKind::kImage : HduKind::kEmpty;
}

// --- header keywords ------------------------------------------------------------------------------

// The keyword's value field as written (strings keep their quotes; "" = no value), or nullopt if
// the keyword is absent from the current HDU.
std::optional<std::string> FitsFile::raw_key(const std::string& key) {
  fitsfile* f = as_fits(handle());
  // CFITSIO treats these as wildcards in keyword lookups; FITS keywords never contain them.
  if (key.empty() || key.find_first_of("*?#") != std::string::npos) {
    fail("invalid header keyword name '" + key + "'");
  }
  char value[FLEN_VALUE] = {};
  char comment[FLEN_COMMENT] = {};
  int status = 0;
  fits_read_keyword(f, key.c_str(), value, comment, &status);
  if (status == KEY_NO_EXIST) {
    fits_clear_errmsg();
    return std::nullopt;
  }
  if (status != 0) fail_status(status, "cannot read header keyword '" + key + "'");
  return std::string(value);
}

namespace {
// CFITSIO's classification of a raw value: 'C' string, 'L' logical, 'I' integer, 'F' float,
// 'X' complex; 0 if unparseable.
char value_type(const std::string& raw) {
  char dtype = 0;
  int status = 0;
  fits_get_keytype(raw.c_str(), &dtype, &status);
  if (status != 0) {
    fits_clear_errmsg();
    return 0;
  }
  return dtype;
}
}  // namespace

std::optional<double> FitsFile::read_key_double(const std::string& key) {
  const auto raw = raw_key(key);
  if (!raw || raw->empty()) return std::nullopt;
  const char type = value_type(*raw);
  if (type != 'I' && type != 'F') fail("keyword '" + key + "' is not a number (value " + *raw + ")");
  double v = 0.0;
  int status = 0;
  fits_read_key(as_fits(handle()), TDOUBLE, key.c_str(), &v, nullptr, &status);
  if (status != 0) fail_status(status, "cannot read keyword '" + key + "' as a number");
  return v;
}

std::optional<long long> FitsFile::read_key_long(const std::string& key) {
  const auto raw = raw_key(key);
  if (!raw || raw->empty()) return std::nullopt;
  const char type = value_type(*raw);
  if (type == 'F') {
    // Accept integral floats ("3.0", "3.9E1"): headers written by float-minded tools use them.
    const double v = *read_key_double(key);
    // 2^63 is exact in double; the range check keeps the conversion defined.
    if (std::trunc(v) == v && v >= -9223372036854775808.0 && v < 9223372036854775808.0) {
      return static_cast<long long>(v);
    }
    fail("keyword '" + key + "' is not an integer (value " + *raw + ")");
  }
  if (type != 'I') fail("keyword '" + key + "' is not a number (value " + *raw + ")");
  // Parsed here, not by CFITSIO: its integer conversion overflows its own message buffer (a
  // fortify abort) on a value it cannot convert, such as one beyond the 64-bit range.
  std::string_view digits(*raw);
  digits.remove_suffix(digits.size() - (digits.find_last_not_of(' ') + 1));
  digits.remove_prefix(std::min(digits.find_first_not_of(' '), digits.size()));
  if (!digits.empty() && digits.front() == '+') digits.remove_prefix(1);
  long long v = 0;
  const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), v);
  if (end != digits.data() + digits.size() || ec == std::errc::invalid_argument) {
    fail("keyword '" + key + "' is not an integer (value " + *raw + ")");
  }
  if (ec != std::errc()) {
    fail("keyword '" + key + "' = " + *raw + " is outside the 64-bit integer range");
  }
  return v;
}

std::optional<std::string> FitsFile::read_key_string(const std::string& key) {
  const auto raw = raw_key(key);
  if (!raw || raw->empty()) return std::nullopt;
  if (raw->front() != '\'') return *raw;  // a number or logical, as written
  // Quoted: let CFITSIO unquote it and follow any CONTINUE cards of a long string.
  char* value = nullptr;
  char comment[FLEN_COMMENT] = {};
  int status = 0;
  fits_read_key_longstr(as_fits(handle()), key.c_str(), &value, comment, &status);
  if (status != 0) {
    if (value != nullptr) {
      int free_status = 0;
      fits_free_memory(value, &free_status);
    }
    fail_status(status, "cannot read keyword '" + key + "' as a string");
  }
  std::string out = value != nullptr ? value : "";
  int free_status = 0;
  fits_free_memory(value, &free_status);
  // FITS: trailing blanks in a string value are not significant.
  out.erase(out.find_last_not_of(' ') + 1);
  return out;
}

namespace {

std::string trim_right(std::string s) {
  s.erase(s.find_last_not_of(' ') + 1);
  return s;
}

// A quoted FITS string value ('it''s  ') unquoted, '' read as ', trailing blanks dropped.
std::string unquote(std::string_view raw) {
  std::string out;
  const std::size_t begin = raw.find('\'');
  for (std::size_t i = begin == std::string_view::npos ? raw.size() : begin + 1; i < raw.size(); ++i) {
    if (raw[i] == '\'') {
      if (i + 1 < raw.size() && raw[i + 1] == '\'') {
        out += '\'';
        ++i;
        continue;
      }
      break;
    }
    out += raw[i];
  }
  return trim_right(std::move(out));
}

}  // namespace

std::vector<FitsFile::HeaderCard> FitsFile::header_cards() {
  fitsfile* f = as_fits(handle());
  int nkeys = 0, more = 0, status = 0;
  fits_get_hdrspace(f, &nkeys, &more, &status);
  if (status != 0) fail_status(status, "cannot read the header");
  std::vector<HeaderCard> cards;
  bool continued = false;  // the last card is a string ending in '&': a CONTINUE card may follow
  for (int k = 1; k <= nkeys; ++k) {
    char record[FLEN_CARD] = {};
    fits_read_record(f, k, record, &status);
    if (status != 0) fail_status(status, "cannot read header card " + std::to_string(k));
    const std::string_view card(record);
    if (continued && card.starts_with("CONTINUE")) {
      // "CONTINUE  'more&' / comment". CFITSIO parses no value on a CONTINUE card, so this one is
      // parsed under a neutral name, as an ordinary card with its value in column 11.
      std::string as_key = "CONTINUX= " + std::string(card.substr(std::min<std::size_t>(10, card.size())));
      char value[FLEN_VALUE] = {}, comment[FLEN_COMMENT] = {};
      fits_parse_value(as_key.data(), value, comment, &status);
      if (status != 0) fail_status(status, "cannot parse header card " + std::to_string(k) + " (CONTINUE)");
      HeaderCard& last = cards.back();
      last.value.pop_back();  // the '&'
      last.value += unquote(value);
      if (comment[0] != '\0') {
        if (!last.comment.empty()) last.comment += ' ';
        last.comment += comment;
      }
      continued = last.value.ends_with('&');
      continue;
    }
    continued = false;
    HeaderCard out;
    char name[FLEN_KEYWORD] = {};
    int length = 0;
    fits_get_keyname(record, name, &length, &status);  // a HIERARCH card's long name
    if (status != 0) fail_status(status, "cannot parse the keyword of header card " + std::to_string(k));
    out.key = trim_right(name);
    // A value indicator is "= " in columns 9-10, or for a HIERARCH card an '=' anywhere.
    const bool hierarch = card.starts_with("HIERARCH ");
    const bool has_value = out.key != "COMMENT" && out.key != "HISTORY" && !out.key.empty() &&
                           (hierarch ? card.find('=') != std::string_view::npos
                                     : card.size() > 8 && card[8] == '=' && (card.size() == 9 || card[9] == ' '));
    if (!has_value) {
      out.value = trim_right(std::string(card.substr(std::min<std::size_t>(8, card.size()))));
      cards.push_back(std::move(out));
      continue;
    }
    char value[FLEN_VALUE] = {}, comment[FLEN_COMMENT] = {};
    fits_parse_value(record, value, comment, &status);
    if (status != 0) fail_status(status, "cannot parse header card " + std::to_string(k) + " ('" + out.key + "')");
    out.comment = trim_right(comment);
    out.comment.erase(0, out.comment.find_first_not_of(' '));
    const std::string raw = value;
    switch (raw.empty() ? '\0' : value_type(raw)) {
      case '\0':
        out.type = raw.empty() ? HeaderCard::Type::kUndefined : HeaderCard::Type::kString;
        out.value = raw;  // a value CFITSIO cannot classify: as written
        break;
      case 'C':
        out.type = HeaderCard::Type::kString;
        out.value = unquote(raw);
        continued = out.value.ends_with('&');
        break;
      case 'L':
        out.type = HeaderCard::Type::kLogical;
        out.value = raw;
        break;
      case 'I':
        out.type = HeaderCard::Type::kInteger;
        out.value = raw;
        break;
      case 'F':
        out.type = HeaderCard::Type::kReal;
        out.value = raw;
        std::ranges::replace_if(out.value, [](char c) { return c == 'D' || c == 'd'; }, 'E');
        break;
      default:  // 'X', complex
        out.type = HeaderCard::Type::kString;
        out.value = raw;
    }
    cards.push_back(std::move(out));
  }
  return cards;
}

double FitsFile::key_double(const std::string& key) {
  if (auto v = read_key_double(key)) return *v;
  fail(raw_key(key) ? "header keyword '" + key + "' has no value"
                    : "missing header keyword '" + key + "'");
}

long long FitsFile::key_long(const std::string& key) {
  if (auto v = read_key_long(key)) return *v;
  fail(raw_key(key) ? "header keyword '" + key + "' has no value"
                    : "missing header keyword '" + key + "'");
}

std::string FitsFile::key_string(const std::string& key) {
  if (auto v = read_key_string(key)) return *v;
  fail(raw_key(key) ? "header keyword '" + key + "' has no value"
                    : "missing header keyword '" + key + "'");
}

void FitsFile::require_writable(const std::string& what) {
  int mode = READONLY;
  int status = 0;
  fits_file_mode(as_fits(handle()), &mode, &status);
  if (status != 0) fail_status(status, "cannot query the file mode");
  // CFITSIO does not reliably refuse writes itself: fits_create_img on a read-only file
  // "succeeds" and the pixel write that follows crashes.
  if (mode != READWRITE) fail(what + ": the file is open read-only");
}

void FitsFile::require_header(const std::string& what) {
  // In a new file with no HDU yet CFITSIO would write the card anyway, leaving the file invalid
  // (no SIMPLE card). Such a file's current header is empty. (fits_get_num_hdus is no help here:
  // it still says 0 just after the first fits_create_img.)
  int nkeys = 0;
  int more = 0;
  int status = 0;
  fits_get_hdrspace(as_fits(handle()), &nkeys, &more, &status);
  if (status != 0) fail_status(status, what);
  if (nkeys == 0) fail(what + ": the file has no HDU yet (write an image first)");
}

void FitsFile::write_key(const std::string& key, double value, const std::string& comment) {
  require_writable("cannot write header keyword '" + key + "'");
  require_header("cannot write header keyword '" + key + "'");
  fitsfile* f = as_fits(handle());
  if (!std::isfinite(value)) fail("cannot write non-finite value to header keyword '" + key + "'");
  int status = 0;
  // -17: "%.17G", enough significant digits for any double to read back bitwise.
  fits_update_key_dbl(f, key.c_str(), value, -17, comment.c_str(), &status);
  if (status != 0) fail_status(status, "cannot write header keyword '" + key + "'");
}

void FitsFile::write_key(const std::string& key, long long value, const std::string& comment) {
  require_writable("cannot write header keyword '" + key + "'");
  require_header("cannot write header keyword '" + key + "'");
  fitsfile* f = as_fits(handle());
  int status = 0;
  fits_update_key_lng(f, key.c_str(), static_cast<LONGLONG>(value), comment.c_str(), &status);
  if (status != 0) fail_status(status, "cannot write header keyword '" + key + "'");
}

void FitsFile::write_key(const std::string& key, const std::string& value,
                         const std::string& comment) {
  require_writable("cannot write header keyword '" + key + "'");
  require_header("cannot write header keyword '" + key + "'");
  fitsfile* f = as_fits(handle());
  int status = 0;
  // The longstr form writes short values as ordinary cards and long ones with CONTINUE cards.
  fits_update_key_longstr(f, key.c_str(), value.c_str(), comment.c_str(), &status);
  if (status != 0) fail_status(status, "cannot write header keyword '" + key + "'");
}

// --- images ---------------------------------------------------------------------------------------

void FitsFile::resolve_auto_image() {
  if (!auto_image_) return;
  auto_image_ = false;
  fitsfile* f = as_fits(fptr_);
  int start = 1;
  fits_get_hdu_num(f, &start);
  if (start != 1) return;  // opened with "[n]" / "[NAME]": respect it
  int status = 0;
  int naxis = 0;
  fits_get_img_dim(f, &naxis, &status);
  if (status != 0 || naxis != 0) {
    if (status != 0) fits_clear_errmsg();  // image_shape() reports the real problem
    return;
  }
  // Primary has no data (e.g. tile-compressed ".fz" files): take the first image HDU with pixels.
  for (int hdunum = 2;; ++hdunum) {
    int type = 0;
    fits_movabs_hdu(f, hdunum, &type, &status);
    if (status != 0) break;  // past the last HDU (or an unreadable one): none found
    if (type != IMAGE_HDU) continue;
    int n = 0;
    fits_get_img_dim(f, &n, &status);
    if (status != 0) break;
    if (n <= 0 || n > 9) continue;
    LONGLONG dims[9] = {};
    fits_get_img_sizell(f, n, dims, &status);
    if (status != 0) break;
    if (std::all_of(dims, dims + n, [](LONGLONG d) { return d > 0; })) return;
  }
  if (status != 0) fits_clear_errmsg();
  restore_hdu(f, start);
}

// What to pass CFITSIO as `nulval` when reading the current image as doubles. Integer images:
// `nan`, so BLANK pixels come back as NaN. Float images: nullptr, which turns CFITSIO's null
// checking off; with it on CFITSIO also flushes -0.0 and denormals to 0, breaking bitwise reads
// (NaNs pass through unchanged either way).
void* FitsFile::image_nulval(double* nan) {
  int bitpix = 0;
  int status = 0;
  fits_get_img_type(as_fits(handle()), &bitpix, &status);  // raw BITPIX, before BSCALE
  if (status != 0) fail_status(status, "cannot read BITPIX");
  return bitpix > 0 ? nan : nullptr;
}

FitsFile::ImageShape FitsFile::image_shape() {
  fitsfile* f = as_fits(handle());
  resolve_auto_image();
  int status = 0;
  int type = 0;
  fits_get_hdu_type(f, &type, &status);
  if (status != 0) fail_status(status, "cannot read HDU type");
  if (type != IMAGE_HDU) fail("not an image HDU (it is a table)");
  int naxis = 0;
  fits_get_img_dim(f, &naxis, &status);
  if (status != 0) fail_status(status, "cannot read NAXIS");
  if (naxis != 2) fail("not a 2-D image (NAXIS = " + std::to_string(naxis) + ")");
  LONGLONG dims[2] = {};
  fits_get_img_sizell(f, 2, dims, &status);
  if (status != 0) fail_status(status, "cannot read image size");
  if (!std::in_range<long>(dims[0]) || !std::in_range<long>(dims[1])) {
    fail("image size " + std::to_string(dims[0]) + " x " + std::to_string(dims[1]) +
         " is out of range");
  }
  require_data_in_file();
  // Pixels the file cannot hold (fuzz finding F19: NAXIS1 = 2^63 - 1 overflowed CFITSIO's end of
  // data, so require_data_in_file passed, and the reader's buffer was asked for 2^63 doubles): a
  // pixel takes a byte at least, or 1/2048 of one in a tile-compressed image (beyond any codec's
  // ratio); the header guard leaves absurd sizes to this check.
  int mode = READWRITE;
  fits_file_mode(f, &mode, &status);
  const bool reading = status == 0 && mode == READONLY;  // a file being written grows as it is written
  status = 0;
  const int compressed = fits_is_compressed_image(f, &status);
  status = 0;
  const long double pixels = static_cast<long double>(dims[0]) * static_cast<long double>(dims[1]);
  const long double bytes = static_cast<long double>(f->Fptr->logfilesize) + 2880;
  if (reading && pixels > (compressed ? 2048 * bytes : bytes))
    fail("image size " + std::to_string(dims[0]) + " x " + std::to_string(dims[1]) + " cannot be in a file of " +
         std::to_string(f->Fptr->logfilesize) + " bytes: the header's sizes are wrong");
  return {static_cast<long>(dims[0]), static_cast<long>(dims[1])};
}

void FitsFile::require_data_in_file() {
  fitsfile* f = as_fits(handle());
  int mode = READWRITE, status = 0;
  fits_file_mode(f, &mode, &status);
  if (status != 0 || mode != READONLY) return;  // a file being written grows as it is written
  LONGLONG head = 0, data = 0, end = 0;
  fits_get_hduaddrll(f, &head, &data, &end, &status);
  if (status != 0) fail_status(status, "cannot read the HDU's position in the file");
  // What CFITSIO parsed, not what the header scan (fits_header_guard) could: it reads values in
  // cards the standard does not allow (fuzz finding F12: "NAXIS1  SEEDBITPIX  = 854775807"), and
  // readers size their buffers from them. The last block's padding may be missing.
  const LONGLONG size = f->Fptr->logfilesize;
  if (end > (size + 2879) / 2880 * 2880)
    fail("its header puts the end of its data at byte " + std::to_string(end) + " but the file holds " +
         std::to_string(size) + " bytes: truncated, or the header's sizes are wrong");
}

void FitsFile::read_image_rows(long y_begin, long n_rows, std::span<double> out) {
  const ImageShape s = image_shape();
  if (y_begin < 0 || n_rows < 0 || y_begin > s.ny - n_rows) {
    fail("cannot read " + std::to_string(n_rows) + " rows from row " + std::to_string(y_begin) +
         ": the image has rows 0.." + std::to_string(s.ny - 1) + " (" + std::to_string(s.nx) +
         " x " + std::to_string(s.ny) + ")");
  }
  if (s.nx != 0 && n_rows > std::numeric_limits<long>::max() / s.nx) fail("image rows too large");
  const long n = n_rows * s.nx;
  if (out.size() != static_cast<std::size_t>(n)) {
    fail("read_image_rows: output holds " + std::to_string(out.size()) + " values, " +
         std::to_string(n_rows) + " rows need " + std::to_string(n));
  }
  if (n == 0) return;
  // Full rows are contiguous on disk, so one read from (1, y_begin + 1) touches only those rows.
  LONGLONG first[2] = {1, static_cast<LONGLONG>(y_begin) + 1};
  double nulval = kNaN;
  int anynul = 0;
  int status = 0;
  fits_read_pixll(as_fits(handle()), TDOUBLE, first, n, image_nulval(&nulval), out.data(), &anynul,
                  &status);
  if (status != 0) {
    fail_status(status, "cannot read image rows " + std::to_string(y_begin) + ".." +
                            std::to_string(y_begin + n_rows - 1));
  }
}

long long FitsFile::image_length() {
  fitsfile* f = as_fits(handle());
  resolve_auto_image();
  int status = 0, type = 0, naxis = 0;
  fits_get_hdu_type(f, &type, &status);
  if (status != 0) fail_status(status, "cannot read HDU type");
  if (type != IMAGE_HDU) fail("not an image HDU (it is a table)");
  fits_get_img_dim(f, &naxis, &status);
  if (status != 0) fail_status(status, "cannot read NAXIS");
  if (naxis != 1) fail("not a 1-D image (NAXIS = " + std::to_string(naxis) + ")");
  LONGLONG length = 0;
  fits_get_img_sizell(f, 1, &length, &status);
  if (status != 0) fail_status(status, "cannot read image size");
  require_data_in_file();
  return static_cast<long long>(length);
}

void FitsFile::read_image_range(long long first, std::span<double> out) {
  const long long length = image_length();
  if (first < 0 || static_cast<long long>(out.size()) > length - first)
    fail("cannot read pixels " + std::to_string(first) + ".." + std::to_string(first + static_cast<long long>(out.size()) - 1) +
         ": the image has " + std::to_string(length));
  if (out.empty()) return;
  LONGLONG start[1] = {static_cast<LONGLONG>(first) + 1};
  double nulval = kNaN;
  int anynul = 0, status = 0;
  fits_read_pixll(as_fits(handle()), TDOUBLE, start, static_cast<LONGLONG>(out.size()), image_nulval(&nulval), out.data(),
                  &anynul, &status);
  if (status != 0) fail_status(status, "cannot read pixels from " + std::to_string(first));
}

std::vector<double> FitsFile::read_image() {
  const ImageShape s = image_shape();
  if (s.nx == 0 || s.ny == 0) return {};
  if (s.ny > std::numeric_limits<long>::max() / s.nx) fail("image too large");
  // Read the last pixel first: a header promising more data than the file holds (truncated or
  // corrupt file) then fails here, before a possibly huge allocation.
  LONGLONG last[2] = {s.nx, s.ny};
  double probe = 0.0;
  int anynul = 0;
  int status = 0;
  fits_read_pixll(as_fits(handle()), TDOUBLE, last, 1, nullptr, &probe, &anynul, &status);
  if (status != 0) fail_status(status, "cannot read image data");
  std::vector<double> pixels(static_cast<std::size_t>(s.nx) * static_cast<std::size_t>(s.ny));
  read_image_rows(0, s.ny, pixels);
  return pixels;
}

void FitsFile::write_empty_image() {
  require_writable("cannot write an image");
  int status = 0;
  fits_create_img(as_fits(handle()), DOUBLE_IMG, 0, nullptr, &status);
  if (status != 0) fail_status(status, "cannot append an empty image HDU");
  auto_image_ = false;
}

void FitsFile::write_image(long nx, long ny, std::span<const double> pixels,
                           const std::string& extname, PixelType type) {
  require_writable("cannot write an image");
  fitsfile* f = as_fits(handle());
  if (nx <= 0 || ny <= 0 || ny > std::numeric_limits<long>::max() / nx) {
    fail("cannot write an image of " + std::to_string(nx) + " x " + std::to_string(ny) +
         " pixels");
  }
  const auto total = static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny);
  if (pixels.size() != total) {
    fail("write_image: got " + std::to_string(pixels.size()) + " pixels for a " +
         std::to_string(nx) + " x " + std::to_string(ny) + " image");
  }
  long naxes[2] = {nx, ny};
  int status = 0;
  // Appended at the end and made current; CFITSIO converts the doubles to BITPIX on writing.
  fits_create_img(f, type == PixelType::kFloat32 ? FLOAT_IMG : type == PixelType::kInt32 ? LONG_IMG : DOUBLE_IMG, 2, naxes,
                  &status);
  if (status != 0) fail_status(status, "cannot append an image HDU");
  auto_image_ = false;
  if (!extname.empty()) write_key("EXTNAME", extname, "extension name");
  // CFITSIO byte-swaps the array it is given in place while writing (its pointer is non-const), so
  // write from a private copy, a chunk at a time to bound the extra memory.
  constexpr std::size_t kChunk = std::size_t{1} << 16;
  std::vector<double> buffer(std::min(kChunk, total));
  for (std::size_t start = 0; start < total; start += kChunk) {
    const std::size_t n = std::min(kChunk, total - start);
    std::copy_n(pixels.begin() + static_cast<std::ptrdiff_t>(start), n, buffer.begin());
    fits_write_img(f, TDOUBLE, static_cast<LONGLONG>(start) + 1, static_cast<LONGLONG>(n),
                   buffer.data(), &status);
    if (status != 0) fail_status(status, "cannot write image pixels");
  }
}

// --- tables ---------------------------------------------------------------------------------------

void FitsFile::require_table() {
  int type = 0;
  int status = 0;
  fits_get_hdu_type(as_fits(handle()), &type, &status);
  if (status != 0) fail_status(status, "cannot read HDU type");
  if (type != BINARY_TBL && type != ASCII_TBL) fail("not a table HDU (it is an image)");
}

long long FitsFile::table_rows() {
  require_table();
  require_data_in_file();
  LONGLONG rows = 0;
  int status = 0;
  fits_get_num_rowsll(as_fits(handle()), &rows, &status);
  if (status != 0) fail_status(status, "cannot read the number of table rows");
  return static_cast<long long>(rows);
}

std::vector<std::string> FitsFile::column_names() {
  require_table();
  fitsfile* f = as_fits(handle());
  int ncols = 0;
  int status = 0;
  fits_get_num_cols(f, &ncols, &status);
  if (status != 0) fail_status(status, "cannot read the number of table columns");
  std::vector<std::string> names;
  for (int col = 1; col <= ncols; ++col) {
    const std::string key = "TTYPE" + std::to_string(col);
    char ttype[FLEN_VALUE] = {};
    fits_read_key(f, TSTRING, key.c_str(), ttype, nullptr, &status);
    if (status == KEY_NO_EXIST) {  // an unnamed column
      fits_clear_errmsg();
      status = 0;
    }
    if (status != 0) fail_status(status, "cannot read " + key);
    names.emplace_back(ttype);
  }
  return names;
}

// 1-based column number of the first column whose TTYPE equals `name` ignoring case. Compared
// here rather than with fits_get_colnum, which treats '*', '?' and '#' as wildcards.
std::optional<int> FitsFile::find_column(const std::string& name) {
  const std::vector<std::string> names = column_names();
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (!names[i].empty() && iequals(names[i], name)) return static_cast<int>(i) + 1;
  }
  return std::nullopt;
}

bool FitsFile::is_integer_column(const std::string& name) {
  void* nulval = nullptr;
  long long repeat = 0;
  const int col = numeric_column(name, &nulval, &repeat);
  int type = 0, status = 0;
  LONGLONG n = 0, width = 0;
  fits_get_eqcoltypell(as_fits(handle()), col, &type, &n, &width, &status);  // after TSCAL/TZERO
  if (status != 0) fail_status(status, "cannot read the type of column '" + name + "'");
  return type != TFLOAT && type != TDOUBLE;  // numeric_column refused every non-numeric type
}

bool FitsFile::has_column(const std::string& name) {
  require_table();
  return find_column(name).has_value();
}

int FitsFile::numeric_column(const std::string& name, void** nulval_if_integer, long long* repeat_out) {
  require_table();
  const auto col = find_column(name);
  if (!col) fail("no column '" + name + "'");
  fitsfile* f = as_fits(handle());
  int type = 0;
  LONGLONG repeat = 0;
  LONGLONG width = 0;
  int status = 0;
  fits_get_eqcoltypell(f, *col, &type, &repeat, &width, &status);  // after TSCAL/TZERO
  if (status != 0) fail_status(status, "cannot read the type of column '" + name + "'");
  if (type < 0) fail("column '" + name + "' is variable-length; only scalar columns can be read");
  if (!is_numeric_column_type(type)) fail("column '" + name + "' is not numeric");
  if (repeat_out) {
    if (repeat < 1) fail("column '" + name + "' has no values per row (repeat " + std::to_string(repeat) + ")");
    *repeat_out = repeat;
  } else if (repeat != 1) {
    fail("column '" + name + "' has " + std::to_string(repeat) +
         " values per row; only scalar columns can be read");
  }
  // Integer columns: TNULL values -> NaN. Float columns: no null checking, which would also flush
  // -0.0 and denormals to 0 (see image_nulval).
  int raw_type = 0;
  fits_get_coltypell(f, *col, &raw_type, &repeat, &width, &status);
  if (status != 0) fail_status(status, "cannot read the type of column '" + name + "'");
  *nulval_if_integer = (raw_type == TFLOAT || raw_type == TDOUBLE) ? nullptr : nulval_if_integer;
  return *col;
}

std::vector<double> FitsFile::read_column(const std::string& name) {
  void* nulval = nullptr;
  numeric_column(name, &nulval);
  const long long rows = table_rows();
  if (rows == 0) return {};
  // Read the last row first so a table claiming more rows than the file holds fails before
  // allocating for them.
  double probe = 0.0;
  read_column_rows(name, rows - 1, std::span<double>(&probe, 1));
  std::vector<double> values(static_cast<std::size_t>(rows));
  read_column_rows(name, 0, values);
  return values;
}

void FitsFile::read_column_rows(const std::string& name, long long first_row, std::span<double> out) {
  read_rows(name, first_row, out, false);
}

void FitsFile::read_column_rows(const std::string& name, long long first_row, std::span<long long> out) {
  read_rows(name, first_row, out, false);
}

void FitsFile::read_columns_rows(long long first_row, std::span<const ColumnOutput> columns) {
  struct Column {
    int number;
    bool integer;
    void* nulval;  // non-null: an integer column read as double, TNULL -> NaN
    void* data;
  };
  std::vector<Column> plan;
  const std::size_t n = columns.empty() ? 0 : std::visit([](auto s) { return s.size(); }, columns.front().out);
  for (const ColumnOutput& c : columns) {
    void* nulval = nullptr;
    const int number = numeric_column(c.name, &nulval);
    const bool integer = std::holds_alternative<std::span<long long>>(c.out);
    if (integer && nulval == nullptr) fail("column '" + c.name + "' is not an integer column");
    const std::size_t size = std::visit([](auto s) { return s.size(); }, c.out);
    if (size != n)
      fail("read_columns_rows: the output of column '" + c.name + "' holds " + std::to_string(size) + " values, that of '" +
           columns.front().name + "' " + std::to_string(n));
    require_rows(c.name, first_row, size, 1);
    plan.push_back({number, integer, nulval, std::visit([](auto s) { return static_cast<void*>(s.data()); }, c.out)});
  }
  if (n == 0) return;
  fitsfile* f = as_fits(handle());
  long block = 0;
  int status = 0;
  fits_get_rowsize(f, &block, &status);  // the rows CFITSIO's buffers hold
  if (status != 0) fail_status(status, "cannot read the table's row size");
  const std::size_t rows_per_block = static_cast<std::size_t>(std::max(block, 1L));
  double nan = kNaN;
  for (std::size_t r = 0; r < n; r += rows_per_block) {
    const auto k = static_cast<LONGLONG>(std::min(rows_per_block, n - r));
    const LONGLONG row = first_row + 1 + static_cast<LONGLONG>(r);
    for (std::size_t i = 0; i < plan.size(); ++i) {
      const Column& c = plan[i];
      int anynul = 0;
      if (c.integer) {
        fits_read_col(f, TLONGLONG, c.number, row, 1, k, nullptr, static_cast<long long*>(c.data) + r, &anynul, &status);
      } else {
        fits_read_col(f, TDOUBLE, c.number, row, 1, k, c.nulval ? &nan : nullptr, static_cast<double*>(c.data) + r,
                      &anynul, &status);
      }
      if (status != 0) fail_status(status, "cannot read column '" + columns[i].name + "'");
    }
  }
}

long long FitsFile::column_repeat(const std::string& name) {
  void* nulval = nullptr;
  long long repeat = 0;
  numeric_column(name, &nulval, &repeat);
  return repeat;
}

void FitsFile::require_rows(const std::string& name, long long first_row, std::size_t values, long long repeat) {
  const long long rows = table_rows();
  if (values % static_cast<std::size_t>(repeat) != 0)
    fail("reading column '" + name + "': " + std::to_string(values) + " values are not whole rows of " +
         std::to_string(repeat));
  const long long n = static_cast<long long>(values / static_cast<std::size_t>(repeat));
  if (first_row < 0 || n > rows - first_row)
    fail("cannot read rows " + std::to_string(first_row) + ".." + std::to_string(first_row + n - 1) + " of column '" +
         name + "': the table has " + std::to_string(rows) + " rows");
}

void FitsFile::read_vector_rows(const std::string& name, long long first_row, std::span<double> out) {
  read_rows(name, first_row, out, true);
}

void FitsFile::read_vector_rows(const std::string& name, long long first_row, std::span<long long> out) {
  read_rows(name, first_row, out, true);
}

void FitsFile::read_rows(const std::string& name, long long first_row, std::span<double> out, bool vector) {
  void* nulval = nullptr;
  long long repeat = 1;
  const int col = numeric_column(name, &nulval, vector ? &repeat : nullptr);
  require_rows(name, first_row, out.size(), repeat);
  if (out.empty()) return;
  double nan = kNaN;
  int anynul = 0, status = 0;
  fits_read_col(as_fits(handle()), TDOUBLE, col, first_row + 1, 1, static_cast<LONGLONG>(out.size()),
                nulval ? &nan : nullptr, out.data(), &anynul, &status);
  if (status != 0) fail_status(status, "cannot read column '" + name + "'");
}

void FitsFile::read_rows(const std::string& name, long long first_row, std::span<long long> out, bool vector) {
  void* nulval = nullptr;
  long long repeat = 1;
  const int col = numeric_column(name, &nulval, vector ? &repeat : nullptr);
  if (nulval == nullptr) fail("column '" + name + "' is not an integer column");
  require_rows(name, first_row, out.size(), repeat);
  if (out.empty()) return;
  int anynul = 0, status = 0;
  fits_read_col(as_fits(handle()), TLONGLONG, col, first_row + 1, 1, static_cast<LONGLONG>(out.size()), nullptr,
                out.data(), &anynul, &status);
  if (status != 0) fail_status(status, "cannot read column '" + name + "'");
}

int FitsFile::column_type(const std::string& name, int* col, long long* repeat) {
  require_table();
  const auto c = find_column(name);
  if (!c) fail("no column '" + name + "'");
  int type = 0, status = 0;
  LONGLONG r = 0, width = 0;
  fits_get_coltypell(as_fits(handle()), *c, &type, &r, &width, &status);
  if (status != 0) fail_status(status, "cannot read the type of column '" + name + "'");
  *col = *c;
  *repeat = r;
  return type;
}

int FitsFile::string_column(const std::string& name, long long* chars) {
  int col = 0;
  long long repeat = 0;
  if (column_type(name, &col, &repeat) != TSTRING) fail("column '" + name + "' is not a character column");
  // CFITSIO writes the string and its terminator: repeat characters at most.
  if (repeat > 1 << 20) fail("column '" + name + "' holds strings of " + std::to_string(repeat) + " characters");
  *chars = repeat;
  return col;
}

bool FitsFile::is_string_column(const std::string& name) {
  int col = 0;
  long long repeat = 0;
  return column_type(name, &col, &repeat) == TSTRING;
}

std::string FitsFile::read_string(const std::string& name, long long row) {
  std::string out;
  read_string_rows(name, row, std::span<std::string>(&out, 1));
  return out;
}

void FitsFile::read_string_rows(const std::string& name, long long first_row, std::span<std::string> out) {
  long long chars = 0;
  const int col = string_column(name, &chars);
  require_rows(name, first_row, out.size(), 1);
  if (out.empty()) return;
  // One read of every row: a buffer of (chars + 1) bytes per row, CFITSIO filling each in turn.
  const auto stride = static_cast<std::size_t>(chars) + 1;
  std::vector<char> buffer(stride * out.size(), '\0');
  std::vector<char*> values(out.size());
  for (std::size_t i = 0; i < out.size(); ++i) values[i] = buffer.data() + i * stride;
  int anynul = 0, status = 0;
  fits_read_col(as_fits(handle()), TSTRING, col, first_row + 1, 1, static_cast<LONGLONG>(out.size()), nullptr,
                values.data(), &anynul, &status);
  if (status != 0) fail_status(status, "cannot read column '" + name + "'");
  for (std::size_t i = 0; i < out.size(); ++i) {
    const void* end = std::memchr(values[i], '\0', stride);
    std::string s(values[i], end ? static_cast<const char*>(end) - values[i] : static_cast<std::ptrdiff_t>(stride));
    while (!s.empty() && s.back() == ' ') s.pop_back();
    out[i] = std::move(s);
  }
}

void FitsFile::write_table(const std::string& extname, const std::vector<OutputColumn>& columns) {
  require_writable("cannot write table '" + extname + "'");
  if (columns.empty()) fail("cannot write table '" + extname + "' without columns");
  const std::size_t rows = columns.front().values.size();
  std::vector<char*> ttype, tform;
  std::vector<std::string> names, forms;
  for (const OutputColumn& c : columns) {
    if (c.values.size() != rows)
      fail("table '" + extname + "': column '" + c.name + "' has " + std::to_string(c.values.size()) +
           " rows, column '" + columns.front().name + "' " + std::to_string(rows));
    names.push_back(c.name);
    forms.push_back(c.integer ? "K" : "D");
  }
  for (std::size_t i = 0; i < columns.size(); ++i) {
    ttype.push_back(names[i].data());
    tform.push_back(forms[i].data());
  }
  fitsfile* f = as_fits(handle());
  int status = 0;
  fits_create_tbl(f, BINARY_TBL, static_cast<LONGLONG>(rows), static_cast<int>(columns.size()), ttype.data(),
                  tform.data(), nullptr, extname.c_str(), &status);
  if (status != 0) fail_status(status, "cannot create table '" + extname + "'");
  auto_image_ = false;
  for (std::size_t i = 0; i < columns.size() && rows > 0; ++i) {
    // CFITSIO byte-swaps its input in place: write from copies.
    if (columns[i].integer) {
      std::vector<long long> v(rows);
      for (std::size_t r = 0; r < rows; ++r) v[r] = std::llround(columns[i].values[r]);
      fits_write_col(f, TLONGLONG, static_cast<int>(i) + 1, 1, 1, static_cast<LONGLONG>(rows), v.data(), &status);
    } else {
      std::vector<double> v = columns[i].values;
      fits_write_col(f, TDOUBLE, static_cast<int>(i) + 1, 1, 1, static_cast<LONGLONG>(rows), v.data(), &status);
    }
    if (status != 0) fail_status(status, "cannot write column '" + columns[i].name + "'");
  }
}

void FitsFile::copy_all_hdus_to(FitsFile& out) {
  out.require_writable("cannot copy HDUs from '" + path_ + "'");
  int status = 0;
  fits_copy_file(as_fits(handle()), as_fits(out.handle()), 1, 1, 1, &status);
  if (status != 0) fail_status(status, "cannot copy HDUs to '" + out.path() + "'");
  out.auto_image_ = false;
}

void FitsFile::add_column(const std::string& name, const std::string& comment) {
  require_writable("cannot add column '" + name + "'");
  require_table();
  if (has_column(name)) fail("cannot add column '" + name + "': the table has one");
  fitsfile* f = as_fits(handle());
  int status = 0, ncols = 0;
  fits_get_num_cols(f, &ncols, &status);
  std::string ttype = name, tform = "D";
  fits_insert_col(f, ncols + 1, ttype.data(), tform.data(), &status);
  if (status == 0 && !comment.empty()) {
    const std::string key = "TCOMM" + std::to_string(ncols + 1);
    fits_update_key_str(f, key.c_str(), comment.c_str(), "", &status);
  }
  if (status != 0) fail_status(status, "cannot add column '" + name + "'");
}

void FitsFile::write_column_rows(const std::string& name, long long first_row, std::span<const double> values) {
  require_writable("cannot write column '" + name + "'");
  require_table();
  const auto col = find_column(name);
  if (!col) fail("no column '" + name + "'");
  if (values.empty()) return;
  std::vector<double> copy(values.begin(), values.end());  // CFITSIO byte-swaps its input in place
  int status = 0;
  fits_write_col(as_fits(handle()), TDOUBLE, *col, static_cast<LONGLONG>(first_row) + 1, 1,
                 static_cast<LONGLONG>(copy.size()), copy.data(), &status);
  if (status != 0) fail_status(status, "cannot write column '" + name + "'");
}

void FitsFile::read_image_region(long x_begin, long y_begin, long nx, long ny, std::span<double> out) {
  const ImageShape s = image_shape();
  if (x_begin < 0 || y_begin < 0 || nx <= 0 || ny <= 0 || x_begin > s.nx - nx || y_begin > s.ny - ny)
    fail("cannot read the " + std::to_string(nx) + " x " + std::to_string(ny) + " region at (" +
         std::to_string(x_begin) + ", " + std::to_string(y_begin) + "): the image is " + std::to_string(s.nx) +
         " x " + std::to_string(s.ny));
  if (out.size() != static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny))
    fail("read_image_region: output holds " + std::to_string(out.size()) + " values");
  long first[2] = {x_begin + 1, y_begin + 1};
  long last[2] = {x_begin + nx, y_begin + ny};
  long inc[2] = {1, 1};
  double nulval = kNaN;
  int anynul = 0, status = 0;
  fits_read_subset(as_fits(handle()), TDOUBLE, first, last, inc, image_nulval(&nulval), out.data(), &anynul, &status);
  if (status != 0) fail_status(status, "cannot read an image region");
}

}  // namespace stampede::io
