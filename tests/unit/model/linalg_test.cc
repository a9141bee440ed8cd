// linear (engine/model/linalg.cc): products less than 8 deep take their own FMA chain, which must give Eigen's
// product bit for bit (the relation MLP's first layer; a rollout must not change with the path its products take).
#include "engine/model/linalg.h"

#include <gtest/gtest.h>

#include <vector>

namespace ss {
namespace {

TEST(Linear, ShallowProductsGiveEigensBitsWithAndWithoutBias) {
  for (int in = 1; in < 8; ++in)
    for (int out : {16, 32, 48})
      for (int rows : {1, 7, 300}) {
        const Mat w = Mat::Random(out, in);
        const Mat b = Mat::Random(1, out);
        Mat x = Mat::Random(rows, in) * 10.0f;
        x(0, 0) = 0.0f;  // exact zeros and cancellations take the same path
        for (const float* bias : {static_cast<const float*>(nullptr), b.data()}) {
          const LinearParams p{w.data(), bias, out, in, nullptr};
          Mat want = x * w.transpose();
          if (bias) want.rowwise() += b.row(0);
          const Mat got = linear(x, p);
          ASSERT_EQ(got.rows(), rows);
          ASSERT_EQ(got.cols(), out);
          for (int i = 0; i < rows; ++i)
            for (int o = 0; o < out; ++o)
              ASSERT_EQ(got(i, o), want(i, o)) << "in " << in << " out " << out << " row " << i << " col " << o;
        }
      }
}

TEST(Linear, OtherShapesKeepTheirValues) {
  const Mat w = Mat::Random(20, 7), x = Mat::Random(5, 7);  // 20 outputs: not whole vectors
  const LinearParams p{w.data(), nullptr, 20, 7, nullptr};
  EXPECT_TRUE(linear(x, p).isApprox(x * w.transpose()));
  const Mat w8 = Mat::Random(32, 8), x8 = Mat::Random(5, 8);  // 8 deep: Eigen's product
  const LinearParams p8{w8.data(), nullptr, 32, 8, nullptr};
  EXPECT_TRUE(linear(x8, p8).isApprox(x8 * w8.transpose()));
}

}  // namespace
}  // namespace ss
