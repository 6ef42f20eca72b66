// Heat map of one value per beam over a source's n x n grid, as a PNG, SVG or
// PDF figure (report/plot_format.h), drawn with cairo.
//
// A calibration report shows, per source, the mean point-to-ray distance of
// every beam's samples as a heat map: it is how a user judges a calibration
// (docs/method.md, "Calibrating a source"). The image is meant to be read
// without any other text:
//
//   - the grid is drawn AS SEEN FROM BEHIND THE SOURCE, LOOKING OUT (along +X):
//     row 0 (largest Z) at the top, col 0 (smallest Y) at the RIGHT, so beam 1
//     is the top-right cell and beam n*n the bottom-left one (docs/method.md
//     "Conventions": beam id = row * n + col + 1);
//   - every cell is filled with the viridis colour of its value (perceptually
//     uniform; 0 dark purple, `scale_max` yellow) and labelled with its beam id
//     (small, top left) and its value (centre), in black or white, whichever
//     contrasts more with the fill;
//   - cells without data (NaN) are light grey (RGB 217,217,217) with darker
//     diagonal hatching and labelled "no data";
//   - a colour bar at the right has ticks and `value_label` (with the unit);
//   - row and column indices, a +Y / +Z axis glyph and a line stating the
//     orientation and the numbering rule are drawn around the grid;
//   - `title` and `subtitle` head the image; when every beam with data is at
//     or below `noise_level`, a line under them says so in bold green:
//     "All beams at the noise level (<= 0.02 mm)", with `noise_note` after
//     the level when set (a map of noise has no
//     pattern to read, and its colours span only the noise);
//   - the colour scale runs from 0 to the largest value, or to `scale_max`
//     when set: maps that share one `scale_max` compare by colour (opl_calibrate
//     gives all sources of a run one scale).
//
// Cells are square, 64 px for n >= 9 and larger for small n (160 px for
// n = 3). docs/report.md shows and explains the image.
#pragma once

#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "opl/core/status.h"
#include "opl/report/plot_format.h"

namespace opl {

// Largest beams_per_side accepted (a 51 x 51 grid is already a ~3400 px image).
inline constexpr int kGridHeatmapMaxBeamsPerSide = 51;

struct GridHeatmap {
  int beams_per_side = 0;        // n: odd, 3 <= n <= kGridHeatmapMaxBeamsPerSide
  std::vector<double> values;    // n*n, values[id - 1] for beam id; >= 0; NaN = no data
  std::string title;             // required, e.g. "Source A: mean point-to-ray distance per beam"
  std::string value_label;       // required, with the unit, e.g. "mean point-to-ray distance [mm]"
  std::string subtitle;          // optional, e.g. "10 slices, 1203 samples, RMS 0.031 mm"
  // Upper end of the colour scale (the lower end is 0); must be finite and
  // > 0 when set. Default: the largest finite value (1 if there is none or it
  // is 0). Values above it take the top colour and the colour bar gets a
  // triangle at its top end; every cell still prints its own value.
  std::optional<double> scale_max;
  // The value's noise level (same unit), NaN = none: when every finite value
  // is <= noise_level the image says "All beams at the noise level
  // (<= <noise_level> <value_unit>)". Must be finite and >= 0 when set.
  double noise_level = std::numeric_limits<double>::quiet_NaN();
  std::string value_unit{};  // e.g. "mm", for that line
  // Why the scale ends where it does, shown after the range in the colour
  // note, e.g. "one scale for sources A, B"; optional.
  std::string scale_note{};
  // Where the noise level comes from, shown in the noise-level line after
  // the level, e.g. "from the session's noise, 95 % family-wise"; optional.
  std::string noise_note{};
};

// The largest finite value over all `heatmaps` (1 if none is > 0): the
// scale_max that makes them share one colour scale, so that equal colours
// mean equal values from one map to the next.
double SharedScaleMax(const std::vector<GridHeatmap>& heatmaps);

// Where things are in the rendered image, in pixels (x right, y down, origin
// at the top-left corner of the image).
struct PixelRect {
  int x = 0;
  int y = 0;
  int width = 0;
  int height = 0;
};

struct GridHeatmapLayout {
  int beams_per_side = 0;
  int image_width = 0;
  int image_height = 0;
  int cell_size = 0;      // square cells, cell_size x cell_size
  PixelRect grid;         // all n x n cells
  PixelRect colour_bar;   // the gradient: bottom row = 0, top row = scale_max
  double scale_max = 0;   // the upper end of the colour scale actually used
  bool all_at_noise_level = false;  // the noise-level line is shown

  // The cell of beam `beam_id` (1 .. n*n): row (id-1)/n from the top, col
  // (id-1)%n from the RIGHT. Cells are separated by 1 px white lines that
  // belong to the cell's rectangle (its right column and bottom row).
  PixelRect CellOfBeam(int beam_id) const;
};

// Checks `heatmap` and computes where everything goes. InvalidArgument with a
// one-line message naming the field, e.g.
//   "GridHeatmap.beams_per_side: must be odd and in [3, 51], got 4"
//   "GridHeatmap.values: has 120 entries, expected beams_per_side^2 = 121"
//   "GridHeatmap.values[4] (beam 5): must be >= 0 or NaN (no data), got -0.1"
//   "GridHeatmap.values[4] (beam 5): must be finite or NaN (no data), got inf"
//   "GridHeatmap.title: must not be empty"
//   "GridHeatmap.value_label: must not be empty (it names the value and its unit)"
//   "GridHeatmap.scale_max: must be finite and > 0, got 0"
//   "GridHeatmap.noise_level: must be finite and >= 0 or NaN (none), got -1"
Result<GridHeatmapLayout> LayoutGridHeatmap(const GridHeatmap& heatmap);

// Renders the heat map in `format` (the bytes of the file; PNG: 8-bit RGB,
// one pixel per layout pixel; `metadata` goes into a PDF's information
// dictionary). Errors as LayoutGridHeatmap; IoError "grid heat map: cannot
// render the png: ..." if cairo fails (e.g. out of memory). Never throws.
Result<std::vector<unsigned char>> RenderGridHeatmap(const GridHeatmap& heatmap,
                                                     PlotFormat format,
                                                     const PlotMetadata& metadata = {});

// Renders in the format `path`'s extension names (.png, .svg, .pdf, any
// case; another is InvalidArgument naming the path) and writes the file
// atomically (opl/io/atomic_file.h): on any error no file is created and an
// existing `path` is left as it was.
Status WriteGridHeatmap(const GridHeatmap& heatmap, const std::string& path,
                        const PlotMetadata& metadata = {});

}  // namespace opl
