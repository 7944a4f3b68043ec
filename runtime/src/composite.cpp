#include "t1rt/composite.hpp"

#include <cmath>
#include <cstdio>

#include "t1_contract.hpp"

namespace t1rt {

const char* member_name(CompositeMember member) { return member == CompositeMember::kGetup ? "getup" : "upright"; }

namespace {
void check_equal_gains(const char* field, const JointArray& getup, const JointArray& upright) {
  for (std::size_t i = 0; i < kJoints; ++i) {
    if (getup[i] != upright[i]) {  // exact: one gain set means the same numbers, not nearly the same
      char why[200];
      std::snprintf(why, sizeof(why),
                    "composite pair differs at joint %zu (%s): getup %g, upright %g; both "
                    "policies must use one gain set",
                    i, t1::kJointNames[i], getup[i], upright[i]);
      throw ArtifactError(field, why);
    }
  }
}
}  // namespace

void check_composite_pair(const PolicyArtifact& getup, const PolicyArtifact& upright) {
  check_equal_gains("kp", getup.kp, upright.kp);
  check_equal_gains("kd", getup.kd, upright.kd);
  if (std::fabs(getup.control_dt_s - upright.control_dt_s) > kControlDtToleranceS)
    throw ArtifactError("control_dt", "composite pair: getup and upright control_dt differ");
}

}  // namespace t1rt
