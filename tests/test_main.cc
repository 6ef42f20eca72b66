// Shared main of every OPL test: fixes the random seeds so that runs repeat.
#include <cstdlib>

#include <gtest/gtest.h>

int main(int argc, char** argv) {
  std::srand(20261122);
  ::testing::InitGoogleTest(&argc, argv);
  ::testing::GTEST_FLAG(random_seed) = 20261122;
  return RUN_ALL_TESTS();
}
