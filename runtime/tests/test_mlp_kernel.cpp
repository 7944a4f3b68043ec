// The MLP kernel variants (mlp_kernel.hpp): the one dispatched on this CPU against the portable one, within
// float tolerance (never bit-exact: FMA and vector widths round differently), whichever this CPU picks.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "t1rt/mlp_kernel.hpp"
#include "t1rt/policy.hpp"
#include "test_artifact.hpp"

using namespace t1rt;
using namespace t1rt::testing;

namespace {
constexpr float kTolerance = 1e-5f;  // on values of order one; relative above

void expect_close(const Eigen::VectorXf& got, const Eigen::VectorXf& want, const std::string& what) {
  ASSERT_EQ(got.size(), want.size()) << what;
  for (Eigen::Index k = 0; k < got.size(); ++k)
    EXPECT_NEAR(got[k], want[k], kTolerance * std::max(1.0f, std::fabs(want[k]))) << what << " [" << k << "]";
}
}  // namespace

TEST(MlpKernel, SelectedVariantIsOneTheCpuRuns) {
  const mlp_kernel::Variant& v = mlp_kernel::selected_variant();
  const bool avx2_fma = std::strcmp(v.name, "avx2+fma") == 0;
  EXPECT_TRUE(avx2_fma || std::strcmp(v.name, "portable") == 0) << v.name;
  if (avx2_fma) EXPECT_TRUE(__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"));
  std::printf("MLP kernel variant on this CPU: %s\n", v.name);
}

// Odd layer sizes (partial panels, odd input counts), every activation and output rule, inputs from small to
// well outside a normalised observation's range.
TEST(MlpKernel, DispatchedMatchesPortable) {
  std::mt19937 rng(11);
  std::normal_distribution<float> normal(0.0f, 1.0f);
  for (const char* act : {"swish", "elu", "tanh", "relu"})
    for (const char* rule : {"tanh_normal", "linear"}) {
      const PolicyArtifact a =
          load_artifact(write_spec(std::string("kernel_") + act + rule, make_spec({33, 70, 5}, rule, act, 5)));
      Mlp dispatched(a), portable(a, mlp_kernel::portable_variant());
      for (float scale : {0.1f, 1.0f, 10.0f}) {
        Eigen::VectorXf x(a.obs_size);
        for (Eigen::Index k = 0; k < x.size(); ++k) x[k] = scale * normal(rng);
        const Eigen::VectorXf want = portable.run(x);
        expect_close(dispatched.run(x), want, std::string(act) + " " + rule + " x" + std::to_string(scale));
      }
    }
}

TEST(MlpKernel, DispatchedMatchesPortableOnTheStudentShape) {
  const PolicyArtifact a = load_artifact(std::string(T1_GOLDEN_DIR) + "/random_policy.safetensors");
  Mlp dispatched(a), portable(a, mlp_kernel::portable_variant());
  std::mt19937 rng(3);
  std::normal_distribution<float> normal(0.0f, 1.0f);
  for (int trial = 0; trial < 20; ++trial) {
    Eigen::VectorXf x(a.obs_size);
    for (Eigen::Index k = 0; k < x.size(); ++k) x[k] = normal(rng);
    const Eigen::VectorXf want = portable.run(x);
    expect_close(dispatched.run(x), want, "trial " + std::to_string(trial));
  }
}

// The engine faults on a non-finite action: a NaN must come through every variant, never be clamped away.
TEST(MlpKernel, NanPropagatesAndHugeInputsStayFinite) {
  const PolicyArtifact a = load_artifact(write_spec("kernel_nan", make_spec({40, 24}, "tanh_normal", "swish", 9)));
  for (const mlp_kernel::Variant* v : {&mlp_kernel::portable_variant(), &mlp_kernel::selected_variant()}) {
    Mlp mlp(a, *v);
    Eigen::VectorXf x = Eigen::VectorXf::Constant(a.obs_size, 1e4f);
    x[1] = -1e4f;
    EXPECT_TRUE(mlp.run(x).allFinite()) << v->name;
    x[0] = std::numeric_limits<float>::quiet_NaN();
    EXPECT_FALSE(mlp.run(x).allFinite()) << v->name;
  }
}
