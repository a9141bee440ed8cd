#include "tools/dataset/sumo_tools.h"

#include <filesystem>

#include "absl/strings/str_cat.h"
#include "tools/dataset/subprocess.h"

namespace ss::dataset {

absl::StatusOr<SumoTools> find_sumo_tools(const std::string& bin_dir, const std::string& search_path,
                                          const std::string& home, const std::string& python) {
  SumoTools t;
  const std::string hint = bin_dir.empty()
                               ? " (install the Debian packages sumo and sumo-tools, or pass --sumo-bin DIR)"
                               : " (--sumo-bin names the directory holding sumo, netgenerate and netconvert)";
  for (auto [name, out] : {std::pair{"sumo", &t.sumo}, {"netgenerate", &t.netgenerate}, {"netconvert", &t.netconvert}}) {
    auto p = bin_dir.empty() ? find_program(name, search_path) : find_program(bin_dir + "/" + name, "");
    if (!p.ok()) return absl::NotFoundError(absl::StrCat("SUMO is missing: ", p.status().message(), hint));
    *out = *p;
  }
  auto py = find_program(python, search_path);
  if (!py.ok()) return absl::NotFoundError(absl::StrCat("Python for randomTrips.py is missing: ", py.status().message()));
  t.python = *py;
  t.home = home;
  t.random_trips = home + "/tools/randomTrips.py";
  std::error_code ec;
  if (!std::filesystem::is_regular_file(t.random_trips, ec))
    return absl::NotFoundError(absl::StrCat("SUMO's tools are missing: ", t.random_trips,
                                            " does not exist (install the Debian package sumo-tools, or pass "
                                            "--sumo-home DIR)"));
  return t;
}

}  // namespace ss::dataset
