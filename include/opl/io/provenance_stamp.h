// The provenance (io/provenance.h) written into a file's own contents, in
// the place its format keeps for it, so that every file OPL writes says which
// tool and version made it, when, from which command line and inputs
// (issue 18, item 6; docs/formats.md, "Provenance"):
//
//   .json            a top-level "provenance" member appended to the root
//                    object (the text before it is kept byte for byte)
//   .csv .xyz .txt   "# opl ..." comment lines first (after a UTF-8 BOM);
//                    OPL's readers skip '#' lines
//   .ply             "comment opl ..." lines after the "format" line
//   .png             tEXt chunks before IEND: "Software" (tool and version),
//                    "Creation Time" and "opl:provenance" (the JSON object)
//   .jpg .jpeg       COM segments (the JSON object) after the leading APPn
//                    segments (JFIF, EXIF)
//   .svg             a <metadata id="opl-provenance"> element holding the JSON
//                    object (XML-escaped), first child of the root <svg>
//                    (after its <title>)
//   .pdf             refused here: a PDF carries it in its metadata, set when
//                    the PDF is drawn (report/board_print.h,
//                    report/plot_format.h PlotMetadata)
//
// Another extension is refused: InvalidArgument "<path>: no provenance
// format for '.ext' files".
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "opl/core/status.h"
#include "opl/io/provenance.h"

namespace opl {

// `contents` of the file `path` (its extension, case-insensitive, picks the
// format) with `provenance` written in. Errors name `path`: a JSON text whose
// root is not an object, a PLY without a "format" line, bytes that are not a
// PNG, an SVG without an <svg> element.
Result<std::string> StampProvenance(const std::string& path, const std::string& contents,
                                    const Provenance& provenance);

// The tEXt chunks of a PNG (keyword, text) in file order: what StampProvenance
// wrote, for tests and for tools that read a picture's history.
Result<std::vector<std::pair<std::string, std::string>>> PngTextChunks(const std::string& png);

}  // namespace opl
