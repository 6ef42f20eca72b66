#include "opl/io/points_csv.h"

#include <charconv>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace opl {
namespace {

std::string Shortest(double v) {
  char buffer[64];
  return std::string(buffer, std::to_chars(buffer, buffer + sizeof(buffer), v).ptr);
}

TEST(PointsCsv, ScalesXyzAndKeepsEverythingElseVerbatim) {
  const std::string text =
      "id, \"Z\" ,x,note,y\n"
      "T1,0.3,0.1,\"a, \"\"quoted\"\" note\",0.2\n"
      "\n"
      "  T2  ,-1e-3,10,,7\r\n";
  Result<PointsCsv> table = PointsCsv::Parse(text, "p.csv");
  ASSERT_TRUE(table.ok()) << table.status().ToString();
  ASSERT_EQ(table->num_points(), 2);
  EXPECT_EQ(table->points()[0], Eigen::Vector3d(0.1, 0.2, 0.3));
  EXPECT_EQ(table->lines(), (std::vector<int>{2, 4}));
  EXPECT_EQ(table->ids(), (std::vector<std::string>{"T1", "T2"}));  // fields are trimmed
  const double s = 1.0 / 3.0;
  ASSERT_TRUE(table->Scale(s).ok());
  const std::string out = table->Format();
  Result<PointsCsv> back = PointsCsv::Parse(out, "out.csv");
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ASSERT_EQ(back->num_points(), 2);
  // Exactly s * x in double, for every coordinate.
  EXPECT_EQ(back->points()[0], Eigen::Vector3d(s * 0.1, s * 0.2, s * 0.3));
  EXPECT_EQ(back->points()[1], Eigen::Vector3d(s * 10.0, s * 7.0, s * -1e-3));
  // Header and the other fields as they were, quotes and spaces included.
  EXPECT_EQ(out.substr(0, out.find('\n')), "id, \"Z\" ,x,note,y");
  EXPECT_EQ(out, "id, \"Z\" ,x,note,y\n"
                 "T1," + Shortest(s * 0.3) + "," + Shortest(s * 0.1) +
                 ",\"a, \"\"quoted\"\" note\"," + Shortest(s * 0.2) + "\n"
                 "  T2  ," + Shortest(s * -1e-3) + "," + Shortest(s * 10.0) + ",," +
                 Shortest(s * 7.0) + "\n");
}

TEST(PointsCsv, Errors) {
  EXPECT_EQ(PointsCsv::Parse("x,y\n1,2\n", "p.csv").status().message(),
            "p.csv:1: missing column 'z' (a points CSV needs x, y and z columns)");
  EXPECT_EQ(PointsCsv::Parse("x,y,z\n1,2,3\n1,2,inf\n", "p.csv").status().message(),
            "p.csv:3: field 'z': not finite: 'inf'");
  EXPECT_EQ(PointsCsv::Parse("x,y,z\n1,2\n", "p.csv").status().message(),
            "p.csv:2: expected 3 fields (as the header), found 2");
  EXPECT_EQ(PointsCsv::Read("/nonexistent/p.csv").status().code(), StatusCode::kIoError);
  Result<PointsCsv> ok = PointsCsv::Parse("x,y,z\n1,2,3\n", "p.csv");
  ASSERT_TRUE(ok.ok());
  EXPECT_EQ(ok->Scale(0.0).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(ok->points()[0], Eigen::Vector3d(1, 2, 3));  // unchanged
}

TEST(PointsCsv, HeaderOnlyIsAnEmptyTable) {
  Result<PointsCsv> t = PointsCsv::Parse("x,y,z\n", "p.csv");
  ASSERT_TRUE(t.ok());
  EXPECT_EQ(t->num_points(), 0);
  EXPECT_EQ(t->Format(), "x,y,z\n");
}

}  // namespace
}  // namespace opl
