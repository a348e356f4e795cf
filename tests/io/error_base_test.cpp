// Tests for engine/common/error.hpp: every error type of the library derives from stampede::Error,
// so one catch clause maps them all, and each keeps its own message.
#include "engine/common/error.hpp"

#include <gtest/gtest.h>

#include <functional>
#include <map>
#include <string>
#include <type_traits>

#include "io/catalog_writer.hpp"
#include "io/durable_file.hpp"
#include "io/fits_error.hpp"
#include "io/fits_file.hpp"
#include "io/option_registry.hpp"

namespace stampede {
namespace {

static_assert(std::is_base_of_v<std::runtime_error, Error>);
static_assert(std::is_base_of_v<Error, io::FitsError>);
static_assert(std::is_base_of_v<Error, io::ConfigError>);
static_assert(std::is_base_of_v<Error, io::CatalogError>);
static_assert(std::is_base_of_v<Error, io::FileError>);

// The message of the stampede::Error that `body` throws ("" and a failure otherwise).
std::string caught_as_error(const std::function<void()>& body) {
  try {
    body();
  } catch (const Error& e) {
    return e.what();
  } catch (...) {
    ADD_FAILURE() << "not a stampede::Error";
    return "";
  }
  ADD_FAILURE() << "nothing was thrown";
  return "";
}

TEST(ErrorBase, EveryErrorTypeIsCaughtAsStampedeError) {
  EXPECT_NE(caught_as_error([] { io::FitsFile::open_read("/nonexistent/x.fits"); }).find("/nonexistent/x.fits"),
            std::string::npos);
  EXPECT_NE(caught_as_error([] {
              struct Tiny {
                int n = 0;
                std::map<std::string, std::string> explicitly_set;
              } c;
              const io::OptionRegistry<Tiny> options(
                  {io::int_option<Tiny>("numbers", "n", "a number", [](auto& t) -> auto& { return t.n; })});
              options.set(c, "no_such_option", "1");
            }).find("no_such_option"),
            std::string::npos);
  EXPECT_NE(caught_as_error([] { io::CatalogWriter::create(io::CatalogWriterOptions{}); }).find("empty"),
            std::string::npos);
  EXPECT_NE(caught_as_error([] {
              io::CatalogWriterOptions o;
              o.path = "/nonexistent/dir/out.fits";
              io::CatalogWriter::create(o);
            }).find("/nonexistent/dir/out.fits"),
            std::string::npos);
  EXPECT_NE(caught_as_error([] { io::DurableFile::open("/nonexistent/f", io::DurableFile::Mode::kRead); })
                .find("/nonexistent/f"),
            std::string::npos);
}

}  // namespace
}  // namespace stampede
