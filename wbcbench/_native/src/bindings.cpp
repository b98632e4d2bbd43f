// The module: every part of the native tick binds itself in src/bind/ (conversion and
// ownership only, no mathematics there) and registers with WBCBENCH_BIND; this binds them all,
// layer by layer (bind/bind.hpp).
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include <algorithm>
#include <set>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "bind/bind.hpp"

namespace wbcbench {

namespace {

struct Part {
  std::string name;
  Layer layer;
  BindFunction bind;
};

// filled while the module's files are loaded, before NB_MODULE runs (a function-local static,
// so that it exists before the first registration whatever the files' order)
std::vector<Part>& parts() {
  static std::vector<Part> registered;
  return registered;
}

const char* layer_name(Layer layer) {
  switch (layer) {
    case Layer::kCore:
      return "core";
    case Layer::kBase:
      return "base";
    case Layer::kController:
      return "controller";
  }
  return "";
}

}  // namespace

bool register_binding(const char* name, Layer layer, BindFunction bind) {
  parts().push_back({name, layer, bind});
  return true;
}

}  // namespace wbcbench

NB_MODULE(_core, m) {
  using wbcbench::Part;
  m.doc() = "wbcbench's native real-time tick (C++17, Eigen, Pinocchio)";
  m.attr("compiler") = WBCBENCH_COMPILER;
  m.attr("cxx_flags") = WBCBENCH_CXX_FLAGS;
  std::vector<Part> parts = wbcbench::parts();
  std::sort(parts.begin(), parts.end(), [](const Part& a, const Part& b) {
    return std::tie(a.layer, a.name) < std::tie(b.layer, b.name);
  });
  std::set<std::string> names;
  std::vector<std::tuple<std::string, std::string>> bound;
  for (const Part& part : parts) {
    if (!names.insert(part.name).second)
      throw std::runtime_error("wbcbench: two parts of the module are named '" + part.name + "'");
    part.bind(m);
    bound.emplace_back(part.name, wbcbench::layer_name(part.layer));
  }
  // (name, layer) of every part, in the order bound: what a controller's file registered
  m.attr("bindings") = bound;
}
