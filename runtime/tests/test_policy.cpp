// Observation, gait clock, MLP and timing statistics; golden-vector parity with the Python side.
#include <gtest/gtest.h>

#include <cmath>
#include <ctime>
#include <filesystem>
#include <fstream>

#include "t1rt/periodic_task.hpp"
#include "t1rt/policy.hpp"
#include "test_artifact.hpp"

using namespace t1rt;
using namespace t1rt::testing;

TEST(Observation, ProjectedGravity) {
  float g[3];
  const float upright[4] = {1, 0, 0, 0};
  projected_gravity(upright, g);
  EXPECT_NEAR(g[0], 0, 1e-7);
  EXPECT_NEAR(g[1], 0, 1e-7);
  EXPECT_NEAR(g[2], -1, 1e-7);
  // Pitched forward 90 deg about y: gravity points along +x of the IMU frame... R^T(0,0,-1) = (1,0,0).
  const float s = std::sqrt(0.5f);
  const float pitched[4] = {s, 0, s, 0};
  projected_gravity(pitched, g);
  EXPECT_NEAR(g[0], 1, 1e-6);
  EXPECT_NEAR(g[1], 0, 1e-6);
  EXPECT_NEAR(g[2], 0, 1e-6);
}

TEST(Observation, TermsInManifestOrder) {
  const PolicyArtifact a = load_artifact(write_spec("obs", make_spec()));
  float quat[4] = {1, 0, 0, 0}, gyro[3] = {0.1f, 0.2f, 0.3f}, cmd[3] = {0.5f, 0, 0}, phase[2] = {0.3f, -2.0f};
  JointArray q = a.default_pose, dq{}, last{};
  q[14] += 0.25f;
  dq[3] = 1.5f;
  last[22] = -0.7f;
  Eigen::VectorXf obs(a.obs_size);
  build_observation(a, {quat, gyro, cmd, q.data(), dq.data(), last.data(), phase}, obs);
  EXPECT_FLOAT_EQ(obs[1], 0.2f);
  EXPECT_FLOAT_EQ(obs[5], -1.0f);
  EXPECT_FLOAT_EQ(obs[6], 0.5f);
  EXPECT_NEAR(obs[9 + 14], 0.25f, 1e-6);
  EXPECT_FLOAT_EQ(obs[32 + 3], 1.5f);
  EXPECT_FLOAT_EQ(obs[55 + 22], -0.7f);
  EXPECT_FLOAT_EQ(obs[78], std::cos(0.3f));
  EXPECT_FLOAT_EQ(obs[79], std::cos(-2.0f));
  EXPECT_FLOAT_EQ(obs[80], std::sin(0.3f));
  EXPECT_FLOAT_EQ(obs[81], std::sin(-2.0f));
}

TEST(GaitPhase, AdvancesWrapsAndFreezes) {
  GaitPhase p;
  const float go[3] = {0.5f, 0, 0}, still[3] = {0.01f, 0, 0};
  EXPECT_FLOAT_EQ(p.phase()[0], 0.0f);
  EXPECT_NEAR(p.phase()[1], -M_PI, 1e-6);
  p.advance(1.5, 0.02, still, 0.1);
  EXPECT_FLOAT_EQ(p.phase()[0], 0.0f);  // frozen
  p.advance(1.5, 0.02, go, 0.1);
  EXPECT_NEAR(p.phase()[0], 2 * M_PI * 1.5 * 0.02, 1e-6);
  for (int i = 0; i < 1000; ++i) p.advance(1.5, 0.02, go, 0.1);
  for (int k = 0; k < 2; ++k) {
    EXPECT_GE(p.phase()[k], -M_PI - 1e-6);
    EXPECT_LT(p.phase()[k], M_PI);
  }
  // Offsets stay pi apart (mod 2 pi).
  EXPECT_NEAR(std::cos(p.phase()[0] - p.phase()[1]), -1.0, 1e-4);
}

// The MLP against a straightforward double-precision reference, for every activation and output rule, with
// the portable kernel and the one dispatched on this CPU (mlp_kernel.hpp).
TEST(Mlp, MatchesReferenceForEveryActivation) {
  for (const mlp_kernel::Variant* variant : {&mlp_kernel::portable_variant(), &mlp_kernel::selected_variant()})
    for (const char* act : {"swish", "elu", "tanh", "relu"})
      for (const char* rule : {"tanh_normal", "linear"}) {
        const ArtifactSpec spec = make_spec({16, 8}, rule, act, 3);
        PolicyArtifact a = load_artifact(write_spec(std::string("mlp_") + act + rule, spec));
        Mlp mlp(a, *variant);
        Eigen::VectorXf x = Eigen::VectorXf::LinSpaced(a.obs_size, -2.0f, 2.0f);
        const Eigen::VectorXf y = mlp.run(x);
        Eigen::VectorXd h = x.cast<double>();
        for (std::size_t i = 0; i < a.layers.size(); ++i) {
          h = a.layers[i].weight.cast<double>() * h + a.layers[i].bias.cast<double>();
          if (i + 1 == a.layers.size()) break;
          for (int k = 0; k < h.size(); ++k) {
            const double v = h[k];
            h[k] = std::string(act) == "swish"  ? v / (1 + std::exp(-v))
                   : std::string(act) == "elu"  ? (v > 0 ? v : std::expm1(v))
                   : std::string(act) == "tanh" ? std::tanh(v)
                                                : std::max(v, 0.0);
          }
        }
        ASSERT_EQ(y.size(), 23);
        for (int k = 0; k < 23; ++k) {
          const double ref = std::string(rule) == "tanh_normal" ? std::tanh(h[k]) : h[k];
          EXPECT_NEAR(y[k], ref, 1e-5) << variant->name << " " << act << " " << rule << " " << k;
        }
      }
}

TEST(TimingStats, LastMeanP99Max) {
  TimingStats t;
  for (int i = 1; i <= 100; ++i) t.add(i);
  EXPECT_DOUBLE_EQ(t.last(), 100);
  EXPECT_DOUBLE_EQ(t.mean(), 50.5);
  EXPECT_DOUBLE_EQ(t.max(), 100);
  EXPECT_NEAR(t.p99(), 100, 1.0);
  for (std::size_t i = 0; i < kTimingWindow; ++i) t.add(1.0);  // window forgets; max does not
  EXPECT_DOUBLE_EQ(t.p99(), 1.0);
  EXPECT_DOUBLE_EQ(t.max(), 100);
}

// Behaviour only (lower bounds): how far past a deadline the OS wakes us depends on the machine's load,
// so the rate itself is measured by `make bench`, not asserted here.
TEST(PeriodicTask, NeverWakesBeforeItsAbsoluteDeadline) {
  PeriodicTask task(kLoopPeriodNs);
  const int64_t t0 = monotonic_ns();
  task.start();
  for (int i = 0; i < 50; ++i) {
    // Deadlines are absolute and a re-phase after an overrun only moves them later, so tick i never
    // wakes before the (i+1)-th grid point after start, however late earlier ticks were.
    EXPECT_GE(task.wait_next(), t0 + (i + 1) * kLoopPeriodNs) << "tick " << i;
    task.end_compute();
  }
  EXPECT_GE(monotonic_ns() - t0, 50 * kLoopPeriodNs);
  EXPECT_EQ(task.lateness().count(), 50);
  EXPECT_EQ(task.compute().count(), 50);
}

TEST(PeriodicTask, MissedPeriodIsCountedAndRePhasedWithoutABurst) {
  PeriodicTask task(kLoopPeriodNs);
  task.start();
  task.wait_next();
  const int64_t overruns_before = task.overruns();                // a loaded machine may already have overrun
  const timespec stall{0, static_cast<long>(3 * kLoopPeriodNs)};  // a tick that overruns by > 1 period
  nanosleep(&stall, nullptr);
  const int64_t late_wake_ns = task.wait_next();
  EXPECT_EQ(task.overruns(), overruns_before + 1);
  // No catch-up burst: the tick after the overrun still waits a whole period.
  EXPECT_GE(task.wait_next() - late_wake_ns, kLoopPeriodNs);
}

// Golden vectors written by common/observation.py + training/export/brax.py.
TEST(Golden, ObservationAndActionMatchPython) {
  const std::filesystem::path dir = T1_GOLDEN_DIR;
  const auto json_path = dir / "golden_vectors.json";
  if (!std::filesystem::exists(json_path))
    GTEST_SKIP() << "no " << json_path << " yet (written by training/export/brax.py)";
  std::ifstream in(json_path);
  const nlohmann::json g = nlohmann::json::parse(in);
  const PolicyArtifact a = load_artifact((dir / g.at("artifact").get<std::string>()).string());
  const double tol = g.value("tolerance", 1e-5);
  for (const mlp_kernel::Variant* variant : {&mlp_kernel::portable_variant(), &mlp_kernel::selected_variant()}) {
    SCOPED_TRACE(variant->name);
    Mlp mlp(a, *variant);
    int index = 0;
    for (const auto& c : g.at("cases")) {
      auto vec = [&](const char* key) { return c.at(key).get<std::vector<float>>(); };
      const auto quat = vec("imu_quat"), gyro = vec("gyro"), cmd = vec("command"), q = vec("q"), dq = vec("dq"),
                 last = vec("last_action"), phase = vec("gait_phase");
      Eigen::VectorXf obs(a.obs_size);
      build_observation(a, {quat.data(), gyro.data(), cmd.data(), q.data(), dq.data(), last.data(), phase.data()}, obs);
      const Eigen::VectorXf norm = (obs - a.obs_mean).cwiseQuotient(a.obs_std);
      const Eigen::VectorXf action = mlp.run(norm);
      auto expect_near = [&](const char* key, const float* got, std::size_t n) {
        const auto want = vec(key);
        ASSERT_EQ(want.size(), n) << key << " case " << index;
        for (std::size_t k = 0; k < n; ++k) EXPECT_NEAR(got[k], want[k], tol) << key << "[" << k << "] case " << index;
      };
      expect_near("obs", obs.data(), obs.size());
      expect_near("obs_normalized", norm.data(), norm.size());
      expect_near("action", action.data(), action.size());
      JointArray target{};
      for (std::size_t j = 0; j < kJoints; ++j) target[j] = a.default_pose[j] + a.action_scale[j] * action[j];
      expect_near("q_target", target.data(), kJoints);
      ++index;
    }
    EXPECT_GT(index, 0);
  }
}

// The training envs observe the gait clock before advancing it (reset observation = initial phase), so the
// engine's first policy tick must show the initial phase and the second one a single advance.
TEST(PolicyEngine, ObservesThePhaseBeforeAdvancingIt) {
  const std::filesystem::path dir = T1_GOLDEN_DIR;
  PolicyEngine engine(load_artifact((dir / "random_policy.safetensors").string()));
  const PolicyArtifact& a = engine.artifact();
  std::size_t phase_at = 0;
  for (const auto& t : a.obs_terms) {
    if (t.name == "phase") break;
    phase_at += static_cast<std::size_t>(t.size);
  }
  ASSERT_LT(phase_at, static_cast<std::size_t>(a.obs_size));
  const float quat[4] = {1, 0, 0, 0}, gyro[3] = {0, 0, 0}, walk[3] = {0.5f, 0, 0};
  JointArray q = a.default_pose, dq{};
  ASSERT_EQ(engine.step(quat, gyro, walk, q.data(), dq.data()), PolicyEngine::Result::kOk);
  EXPECT_FLOAT_EQ(engine.obs_raw()[phase_at + 0], 1.0f);     // cos(0)
  EXPECT_NEAR(engine.obs_raw()[phase_at + 1], -1.0f, 1e-6);  // cos(-pi)
  ASSERT_EQ(engine.step(quat, gyro, walk, q.data(), dq.data()), PolicyEngine::Result::kOk);
  const double advanced = 2 * M_PI * a.gait_frequency_hz * a.control_dt_s;
  EXPECT_NEAR(engine.obs_raw()[phase_at + 0], std::cos(advanced), 1e-5);
}
