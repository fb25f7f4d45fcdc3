/* make_jpeg_seeds.c — writes the JPEG seeds of tests/fuzz/corpus/jpeg with libjpeg: baseline
 * RGB 4:2:0, greyscale, progressive, restart markers, arithmetic-free. Run once by
 * make_seeds.sh; the outputs are committed.  usage: make_jpeg_seeds OUTPUT_FOLDER */
#include <stdio.h> /* before jpeglib.h, which uses FILE and size_t */
#include <stdlib.h>

#include <jpeglib.h>

static void write_jpeg(const char *folder, const char *name, int w, int h, int grey, int progressive, int restart) {
    char path[512];
    snprintf(path, sizeof path, "%s/%s", folder, name);
    FILE *f = fopen(path, "wb");
    if (!f) exit(1);
    struct jpeg_compress_struct c;
    struct jpeg_error_mgr e;
    c.err = jpeg_std_error(&e);
    jpeg_create_compress(&c);
    jpeg_stdio_dest(&c, f);
    c.image_width = (JDIMENSION)w;
    c.image_height = (JDIMENSION)h;
    c.input_components = grey ? 1 : 3;
    c.in_color_space = grey ? JCS_GRAYSCALE : JCS_RGB;
    jpeg_set_defaults(&c);
    jpeg_set_quality(&c, 75, TRUE);
    if (progressive) jpeg_simple_progression(&c);
    c.restart_interval = (unsigned)restart;
    jpeg_start_compress(&c, TRUE);
    unsigned char row[3 * 64];
    while (c.next_scanline < c.image_height) {
        for (int x = 0; x < w * c.input_components; x++)
            row[x] = (unsigned char)((x * 7 + (int)c.next_scanline * 13) & 255);
        JSAMPROW r = row;
        jpeg_write_scanlines(&c, &r, 1);
    }
    jpeg_finish_compress(&c);
    jpeg_destroy_compress(&c);
    fclose(f);
}

int main(int argc, char **argv) {
    if (argc != 2) return 2;
    write_jpeg(argv[1], "baseline.jpg", 16, 16, 0, 0, 0);
    write_jpeg(argv[1], "grey.jpg", 9, 7, 1, 0, 0);
    write_jpeg(argv[1], "progressive.jpg", 24, 8, 0, 1, 0);
    write_jpeg(argv[1], "restart.jpg", 32, 16, 0, 0, 1);
    return 0;
}
