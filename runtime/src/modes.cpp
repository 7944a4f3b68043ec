// The supervisor's modes by name: what the status reports and what `set_mode` accepts. Text only: every
// rule about entering a mode lives in safety_supervisor.cpp.
#include <cstring>

#include "t1rt/safety.hpp"

namespace t1rt {

const char* mode_name(Mode mode) {
  switch (mode) {
    case Mode::kPassive:
      return "PASSIVE";
    case Mode::kDamping:
      return "DAMPING";
    case Mode::kPrepare:
      return "PREPARE";
    case Mode::kPolicy:
      return "POLICY";
    case Mode::kFault:
      return "FAULT";
  }
  return "?";
}

bool parse_mode(const char* text, Mode* mode) {
  static const struct {
    const char* name;
    Mode mode;
  } kModes[] = {
      {"passive", Mode::kPassive}, {"damping", Mode::kDamping}, {"prepare", Mode::kPrepare}, {"policy", Mode::kPolicy}};
  for (const auto& m : kModes)
    if (std::strcmp(text, m.name) == 0) {
      *mode = m.mode;
      return true;
    }
  return false;
}

}  // namespace t1rt
