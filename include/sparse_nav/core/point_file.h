#ifndef SPARSE_NAV_CORE_POINT_FILE_H
#define SPARSE_NAV_CORE_POINT_FILE_H

#include <cstddef>
#include <string>

#include "sparse_nav/core/types.h"

namespace sparse_nav
{
/// @brief Result of readPointFile: the points in the file's own frame and units, or an error.
struct PointFileResult
{
  bool ok = false;
  std::string error;           ///< starts with the path; says what is wrong (empty when ok)
  PointList points;            ///< finite points only
  std::string format;          ///< "text", "ply" or "pcd"
  std::size_t n_rows = 0;      ///< points stored in the file
  std::size_t n_non_finite = 0;  ///< rows dropped because a coordinate was NaN or infinite
  std::size_t n_columns = 0;   ///< values per row (text: the largest count on a data line)
};

/**
 * @brief Reads x, y, z from a point file; never throws.
 *
 * Text (csv/txt/xyz): one point per line, >= 3 numeric fields separated by commas, semicolons,
 * tabs or spaces; extra columns and trailing empty fields are ignored; blank lines, '#' comments
 * and one leading header line of words are skipped. PLY: ascii, binary_little_endian and
 * binary_big_endian with numeric x/y/z vertex properties. PCD: via pcl::io::loadPCDFile (ascii,
 * binary, binary_compressed) with x/y/z fields. Rows with NaN/Inf are dropped and counted; a file
 * with no finite point, fewer than 3 columns, binary content that is not PLY/PCD, or a malformed
 * header is an error.
 */
PointFileResult readPointFile(const std::string& path);

}  // namespace sparse_nav

#endif  // SPARSE_NAV_CORE_POINT_FILE_H
