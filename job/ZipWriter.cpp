#include "ZipWriter.h"

#include <filesystem>
#include <zip.h>

#include "core/Error.h"

namespace splatwarp {

void writeZip(const std::string& zipPath, const std::string& dir, const std::vector<std::string>& files)
{
    int error = 0;
    zip_t* archive = zip_open(zipPath.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &error);
    if (!archive) {
        zip_error_t e;
        zip_error_init_with_code(&e, error);
        const std::string what = zip_error_strerror(&e);
        zip_error_fini(&e);
        throw IoError(msg(zipPath, ": cannot create zip: ", what));
    }
    auto fail = [&](const std::string& what) {
        const std::string detail = zip_strerror(archive);
        zip_discard(archive); // nothing is written
        throw IoError(msg(zipPath, ": ", what, ": ", detail));
    };
    for (const std::string& name : files) {
        const std::string path = (std::filesystem::path(dir) / name).string();
        zip_source_t* source = zip_source_file(archive, path.c_str(), 0, -1);
        if (!source) fail(msg("cannot read ", path));
        const zip_int64_t index = zip_file_add(archive, name.c_str(), source, ZIP_FL_ENC_UTF_8 | ZIP_FL_OVERWRITE);
        if (index < 0) {
            zip_source_free(source);
            fail(msg("cannot add ", name));
        }
        if (zip_set_file_compression(archive, zip_uint64_t(index), ZIP_CM_STORE, 0) < 0) fail("cannot store " + name);
    }
    if (zip_close(archive) < 0) fail("cannot write");
}

} // namespace splatwarp
