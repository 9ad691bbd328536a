// kdrt-view's overlay text: a 3x5 pixel font of capitals, digits and the punctuation of the help,
// drawn scaled into a 32-bit pixel buffer. Lower case is drawn as capitals; anything else as '?'.
#pragma once

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace view {

// Each glyph: 5 rows of 3 columns, '#' set.
inline const char *glyph(char c)
{
    static const struct {
        char c;
        const char *rows;
    } font[] = {
        {'A', ".#.#.#####.##.#"}, {'B', "##.#.###.#.###."}, {'C', ".###..#..#...##"},
        {'D', "##.#.##.##.###."}, {'E', "####..##.#..###"}, {'F', "####..##.#..#.."},
        {'G', ".###..#.##.#.##"}, {'H', "#.##.#####.##.#"}, {'I', "###.#..#..#.###"},
        {'J', "..#..#..##.#.#."}, {'K', "#.##.###.#.##.#"}, {'L', "#..#..#..#..###"},
        {'M', "#.########.##.#"}, {'N', "##.#.##.##.##.#"}, {'O', ".#.#.##.##.#.#."},
        {'P', "##.#.###.#..#.."}, {'Q', ".#.#.##.###..##"}, {'R', "##.#.###.#.##.#"},
        {'S', ".###...#...###."}, {'T', "###.#..#..#..#."}, {'U', "#.##.##.##.####"},
        {'V', "#.##.##.##.#.#."}, {'W', "#.##.########.#"}, {'X', "#.##.#.#.#.##.#"},
        {'Y', "#.##.#.#..#..#."}, {'Z', "###..#.#.#..###"}, {'0', "####.##.##.####"},
        {'1', ".#.##..#..#.###"}, {'2', "##...#.#.#..###"}, {'3', "##...#.#...###."},
        {'4', "#.##.####..#..#"}, {'5', "####..##...###."}, {'6', ".###..####.####"},
        {'7', "###..#.#..#..#."}, {'8', "####.#####.####"}, {'9', "####.####..###."},
        {'.', ".............#."}, {',', "..........#.#.."}, {':', "....#.....#...."},
        {'/', "..#..#.#.#..#.."}, {'(', ".#.#..#..#...#."}, {')', ".#...#..#..#.#."},
        {'-', "......###......"}, {'+', "....#.###.#...."}, {'[', "##.#..#..#..##."},
        {']', ".##..#..#..#.##"}, {'=', "...###...###..."}, {'%', "#.#..#.#.#..#.#"},
        {'\'', ".#..#.........."}, {'?', "##...#.#.....#."}, {' ', "..............."}, {'_', "............###"},
    };
    if (c >= 'a' && c <= 'z') c = char(c - 'a' + 'A');
    for (const auto &g : font)
        if (g.c == c) return g.rows;
    return glyph('?');
}

// Draws text with its top left corner at (x, y), each font pixel a scale x scale square, in
// `colour` (0xAARRGGBB); pixels outside the width x height buffer are skipped. Characters advance
// 4 font pixels, lines ('\n') 7.
inline void draw_text(std::vector<uint32_t> &pixels, int width, int height, int x, int y, int scale,
                      uint32_t colour, const std::string &text)
{
    int cx = x;
    for (const char c : text) {
        if (c == '\n') {
            cx = x, y += 7 * scale;
            continue;
        }
        const char *rows = glyph(c);
        for (int i = 0; i < 15; ++i) {
            if (rows[i] != '#') continue;
            for (int dy = 0; dy < scale; ++dy)
                for (int dx = 0; dx < scale; ++dx) {
                    const int px = cx + (i % 3) * scale + dx, py = y + (i / 3) * scale + dy;
                    if (px >= 0 && py >= 0 && px < width && py < height) pixels[size_t(py) * size_t(width) + size_t(px)] = colour;
                }
        }
        cx += 4 * scale;
    }
}

}  // namespace view
