// A fresh, empty folder for one test, under the system's temporary folder, removed with whatever
// the test left in it.
#pragma once

#include <catch2/catch.hpp>

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>
#include <vector>

namespace kt {

struct TempDir {
    std::filesystem::path path;

    TempDir()
    {
        std::string name = (std::filesystem::temp_directory_path() / "kdrt-test-XXXXXX").string();
        REQUIRE(mkdtemp(&name[0]) != nullptr);
        path = name;
    }
    ~TempDir()
    {
        std::error_code ignored;
        std::filesystem::remove_all(path, ignored);
    }
    TempDir(const TempDir &) = delete;
    TempDir &operator=(const TempDir &) = delete;

    // The path of `name` in the folder (it may name a subfolder).
    std::string file(const std::string &name) const { return (path / name).string(); }
    // Writes `bytes` to `name`, making its folders; returns its path.
    std::string write(const std::string &name, const std::string &bytes) const
    {
        const std::filesystem::path p = path / name;
        std::filesystem::create_directories(p.parent_path());
        std::ofstream(p, std::ios::binary) << bytes;
        return p.string();
    }
    // Makes a FIFO named `name`; returns its path.
    std::string fifo(const std::string &name) const
    {
        const std::string p = file(name);
        REQUIRE(mkfifo(p.c_str(), 0600) == 0);
        return p;
    }
    // The names in the folder, sorted.
    std::vector<std::string> entries() const
    {
        std::vector<std::string> names;
        std::error_code ignored;
        for (const auto &entry : std::filesystem::directory_iterator(path, ignored))
            names.push_back(entry.path().filename().string());
        std::sort(names.begin(), names.end());
        return names;
    }
};

}  // namespace kt
