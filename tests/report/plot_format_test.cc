// The three formats of the report figures (report/plot_format.h): the file
// name picks the format; the PNG shows the series colour at its data point
// and white elsewhere; the SVG is well-formed XML (expat) whose root is the
// figure's size and whose <title> is the figure's title; the PDF starts with
// %PDF, carries the title and the given metadata, and rasterised by poppler's
// pdftoppm (when installed) at 72 dpi shows the same pixels as the PNG.
#include "opl/report/plot_format.h"

#include <expat.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "io/temp_dir.h"
#include "opl/report/grid_heatmap.h"
#include "opl/report/line_plot.h"
#include "report/rgb.h"

namespace opl {
namespace {

using test::PixelAt;
using test::Rgb;
using testing_support::ReadAll;
using testing_support::TempDir;

const Rgb kBlue{0, 114, 178};  // series 0 (Okabe-Ito)
const Rgb kWhite{255, 255, 255};

TEST(PlotFormatTest, TheExtensionPicksTheFormatInAnyCase) {
  EXPECT_EQ(*PlotFormatFromPath("a/b/plot.png"), PlotFormat::kPng);
  EXPECT_EQ(*PlotFormatFromPath("PLOT.PNG"), PlotFormat::kPng);
  EXPECT_EQ(*PlotFormatFromPath("x.Svg"), PlotFormat::kSvg);
  EXPECT_EQ(*PlotFormatFromPath("report.v2/heat.pdf"), PlotFormat::kPdf);
  EXPECT_EQ(PlotFormatFromPath("out/plot.jpg").status().message(),
            "out/plot.jpg: a figure must be named .png, .svg or .pdf (got '.jpg')");
  EXPECT_EQ(PlotFormatFromPath("out.d/plot").status().message(),
            "out.d/plot: a figure must be named .png, .svg or .pdf (got no extension)");
  EXPECT_EQ(PlotFormatFromPath("plot.png").ok(), true);
  EXPECT_STREQ(PlotFormatName(PlotFormat::kSvg), "svg");
}

// A line plot with one series of markers at known values.
LinePlot MarkerPlot() {
  LinePlot plot;
  plot.title = "Spot noise sweep & friends <A>";
  PlotPanel p;
  p.title = "std of L";
  p.x_label = "spot noise (mm)";
  p.y_label = "std of L (mm)";
  PlotSeries s;
  s.label = "Monte Carlo";
  s.x = {0.1, 0.2, 0.3, 0.4};
  s.y = {1.0, 1.5, 1.2, 2.0};
  s.style = PlotSeries::Style::kMarkers;
  p.series = {s};
  plot.panels = {p};
  return plot;
}

std::string Bytes(const Result<std::vector<unsigned char>>& r) {
  return r.ok() ? std::string(r->begin(), r->end()) : std::string();
}

struct SvgFacts {
  bool well_formed = false;
  std::string error;
  std::string root;
  std::string width, height;
  std::string title;  // text of the root's <title>
};

SvgFacts ParseSvg(const std::string& svg) {
  struct State {
    SvgFacts facts;
    int depth = 0;
    bool in_title = false;
  } state;
  XML_Parser parser = XML_ParserCreate(nullptr);
  XML_SetUserData(parser, &state);
  XML_SetElementHandler(
      parser,
      [](void* data, const XML_Char* name, const XML_Char** attrs) {
        State& s = *static_cast<State*>(data);
        if (s.depth == 0) {
          s.facts.root = name;
          for (int i = 0; attrs[i] != nullptr; i += 2) {
            if (std::string(attrs[i]) == "width") s.facts.width = attrs[i + 1];
            if (std::string(attrs[i]) == "height") s.facts.height = attrs[i + 1];
          }
        }
        s.in_title = s.depth == 1 && std::string(name) == "title";
        ++s.depth;
      },
      [](void* data, const XML_Char*) {
        State& s = *static_cast<State*>(data);
        --s.depth;
        s.in_title = false;
      });
  XML_SetCharacterDataHandler(parser, [](void* data, const XML_Char* text, int length) {
    State& s = *static_cast<State*>(data);
    if (s.in_title) s.facts.title.append(text, static_cast<size_t>(length));
  });
  state.facts.well_formed =
      XML_Parse(parser, svg.data(), static_cast<int>(svg.size()), /*isFinal=*/1) ==
      XML_STATUS_OK;
  if (!state.facts.well_formed) state.facts.error = XML_ErrorString(XML_GetErrorCode(parser));
  XML_ParserFree(parser);
  return state.facts;
}

bool HavePdftoppm() { return std::system("pdftoppm -v >/dev/null 2>&1") == 0; }

// The PDF rasterised at 72 dpi (1 pt = 1 layout pixel), as BGR.
cv::Mat Rasterise(const TempDir& dir, const std::string& pdf) {
  const std::string path = dir.Write("figure.pdf", pdf);
  const std::string command =
      "pdftoppm -r 72 -png -singlefile '" + path + "' '" + dir.File("page") + "'";
  if (std::system(command.c_str()) != 0) return cv::Mat();
  return cv::imread(dir.File("page.png"), cv::IMREAD_COLOR);
}

bool Near(const Rgb& a, const Rgb& b, int tolerance) {
  return std::abs(a.r - b.r) <= tolerance && std::abs(a.g - b.g) <= tolerance &&
         std::abs(a.b - b.b) <= tolerance;
}

TEST(LinePlotFormatsTest, PngSvgAndPdfShowTheSameFigure) {
  const LinePlot plot = MarkerPlot();
  Result<LinePlotLayout> layout = LayoutLinePlot(plot);
  ASSERT_TRUE(layout.ok());
  const LinePlotPanelLayout& p = layout->panels[0];
  const int x1 = static_cast<int>(std::lround(p.PixelX(0.2)));
  const int y1 = static_cast<int>(std::lround(p.PixelY(1.5)));
  // Between grid lines (ticks every 0.05 and 0.2) and away from markers: white.
  const int empty_x = static_cast<int>(std::lround(p.PixelX(0.325)));
  const int empty_y = static_cast<int>(std::lround(p.PixelY(1.7)));

  // PNG: the series colour at its data point, white away from everything.
  const std::string png = Bytes(RenderLinePlot(plot, PlotFormat::kPng));
  const cv::Mat img = cv::imdecode(std::vector<unsigned char>(png.begin(), png.end()),
                                   cv::IMREAD_COLOR);
  ASSERT_FALSE(img.empty());
  EXPECT_EQ(img.cols, layout->image_width);
  EXPECT_EQ(img.rows, layout->image_height);
  EXPECT_EQ(PixelAt(img, x1, y1), kBlue);
  EXPECT_EQ(PixelAt(img, empty_x, empty_y), kWhite);

  // SVG: well-formed, the figure's size in px, its title as <title>.
  const std::string svg = Bytes(RenderLinePlot(plot, PlotFormat::kSvg));
  const SvgFacts facts = ParseSvg(svg);
  EXPECT_TRUE(facts.well_formed) << facts.error;
  EXPECT_EQ(facts.root, "svg");
  EXPECT_EQ(facts.width, std::to_string(layout->image_width) + "px");
  EXPECT_EQ(facts.height, std::to_string(layout->image_height) + "px");
  EXPECT_EQ(facts.title, plot.title);

  // PDF: a PDF with the title and the metadata; rasterised: the PNG's
  // pixels up to anti-aliasing.
  PlotMetadata metadata;
  metadata.creator = "OPL opl_test 1.0";
  metadata.subject = "{\"tool\": \"opl_test\"}";
  const std::string pdf = Bytes(RenderLinePlot(plot, PlotFormat::kPdf, metadata));
  ASSERT_EQ(pdf.compare(0, 5, "%PDF-"), 0);
  EXPECT_NE(pdf.find("/Creator (OPL opl_test 1.0)"), std::string::npos);
  EXPECT_NE(pdf.find("/Title (Spot noise sweep & friends <A>)"), std::string::npos);
  if (!HavePdftoppm()) GTEST_SKIP() << "pdftoppm (poppler-utils) not installed";
  TempDir dir;
  const cv::Mat page = Rasterise(dir, pdf);
  ASSERT_FALSE(page.empty());
  EXPECT_EQ(page.cols, layout->image_width);
  EXPECT_EQ(page.rows, layout->image_height);
  EXPECT_TRUE(Near(PixelAt(page, x1, y1), kBlue, 3)) << PixelAt(page, x1, y1);
  EXPECT_EQ(PixelAt(page, empty_x, empty_y), kWhite);
  // The frame: black in both.
  EXPECT_EQ(PixelAt(page, p.plot_area.x - 1, p.plot_area.y + 40), (Rgb{0, 0, 0}));
}

TEST(LinePlotFormatsTest, WriteLinePlotPicksTheFormatFromThePath) {
  TempDir dir;
  const LinePlot plot = MarkerPlot();
  ASSERT_TRUE(WriteLinePlot(plot, dir.File("a.SVG")).ok());
  // (cairo numbers an SVG's internal ids per process: compare the content.)
  const SvgFacts facts = ParseSvg(ReadAll(dir.File("a.SVG")));
  EXPECT_TRUE(facts.well_formed) << facts.error;
  EXPECT_EQ(facts.title, plot.title);
  ASSERT_TRUE(WriteLinePlot(plot, dir.File("a.pdf")).ok());
  EXPECT_EQ(ReadAll(dir.File("a.pdf")).compare(0, 5, "%PDF-"), 0);
  ASSERT_TRUE(WriteLinePlot(plot, dir.File("a.png")).ok());
  EXPECT_EQ(ReadAll(dir.File("a.png")), Bytes(RenderLinePlotPng(plot)));
  const Status bad = WriteLinePlot(plot, dir.File("a.jpg"));
  EXPECT_EQ(bad.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(bad.message(),
            dir.File("a.jpg") + ": a figure must be named .png, .svg or .pdf (got '.jpg')");
  EXPECT_EQ(dir.Entries(), (std::vector<std::string>{"a.SVG", "a.pdf", "a.png"}));
}

GridHeatmap Heatmap3() {
  GridHeatmap h;
  h.beams_per_side = 3;
  h.values = {0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9};
  h.title = "Source A: mean point-to-ray distance per beam";
  h.value_label = "mean point-to-ray distance [mm]";
  return h;
}

TEST(GridHeatmapFormatsTest, PngSvgAndPdfShowTheSameFigure) {
  const GridHeatmap h = Heatmap3();
  Result<GridHeatmapLayout> layout = LayoutGridHeatmap(h);
  ASSERT_TRUE(layout.ok());
  // Beam 9 (0.9, the top of the scale): viridis yellow near its cell's corner.
  const PixelRect cell = layout->CellOfBeam(9);
  const int x = cell.x + cell.width - 6, y = cell.y + cell.height - 6;
  const Rgb kTop{253, 231, 37};
  const std::string png = Bytes(RenderGridHeatmap(h, PlotFormat::kPng));
  const cv::Mat img = cv::imdecode(std::vector<unsigned char>(png.begin(), png.end()),
                                   cv::IMREAD_COLOR);
  ASSERT_FALSE(img.empty());
  EXPECT_EQ(PixelAt(img, x, y), kTop);
  EXPECT_EQ(PixelAt(img, 3, 3), kWhite);

  const SvgFacts facts = ParseSvg(Bytes(RenderGridHeatmap(h, PlotFormat::kSvg)));
  EXPECT_TRUE(facts.well_formed) << facts.error;
  EXPECT_EQ(facts.width, std::to_string(layout->image_width) + "px");
  EXPECT_EQ(facts.title, h.title);

  const std::string pdf = Bytes(RenderGridHeatmap(h, PlotFormat::kPdf));
  ASSERT_EQ(pdf.compare(0, 5, "%PDF-"), 0);
  if (!HavePdftoppm()) GTEST_SKIP() << "pdftoppm (poppler-utils) not installed";
  TempDir dir;
  const cv::Mat page = Rasterise(dir, pdf);
  ASSERT_FALSE(page.empty());
  EXPECT_EQ(page.cols, layout->image_width);
  EXPECT_TRUE(Near(PixelAt(page, x, y), kTop, 2)) << PixelAt(page, x, y);
  EXPECT_EQ(PixelAt(page, 3, 3), kWhite);
}

TEST(GridHeatmapFormatsTest, WriteGridHeatmapRefusesAnUnknownExtension) {
  TempDir dir;
  EXPECT_EQ(WriteGridHeatmap(Heatmap3(), dir.File("h.bmp")).message(),
            dir.File("h.bmp") + ": a figure must be named .png, .svg or .pdf (got '.bmp')");
  ASSERT_TRUE(WriteGridHeatmap(Heatmap3(), dir.File("h.svg")).ok());
  EXPECT_EQ(dir.Entries(), (std::vector<std::string>{"h.svg"}));
}

}  // namespace
}  // namespace opl
