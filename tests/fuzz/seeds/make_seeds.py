#!/usr/bin/env python3
"""make_seeds.py — writes the small seed corpora of tests/fuzz/corpus (run once; outputs are
committed). PNG, TGA, BMP, HDR, PFM and PLY files are assembled byte by byte here; JPEG comes
from make_jpeg_seeds.c (libjpeg), EXR from penumbra's own writer (penumbra diff --error-image).
usage: make_seeds.py CORPUS_FOLDER PENUMBRA_BINARY JPEG_SEED_BINARY"""
import os, struct, subprocess, sys, zlib

corpus, penumbra, jpeg_tool = sys.argv[1:4]
def out(kind, name, data):
    os.makedirs(os.path.join(corpus, kind), exist_ok=True)
    with open(os.path.join(corpus, kind, name), 'wb') as f:
        f.write(data)

# PNG: chunks with CRCs; colour types 0 (grey, 1 and 8 bit), 2 (RGB 8 and 16 bit), 3 (palette
# with tRNS), 6 (RGBA), one interlaced (Adam7).
def chunk(kind, body):
    return struct.pack('>I', len(body)) + kind + body + struct.pack('>I', zlib.crc32(kind + body) & 0xffffffff)
def png(w, h, depth, color, rows, interlace=0, extra=b''):
    ihdr = struct.pack('>IIBBBBB', w, h, depth, color, 0, 0, interlace)
    raw = b''.join(b'\x00' + r for r in rows)
    return b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', ihdr) + extra + chunk(b'IDAT', zlib.compress(raw)) + chunk(b'IEND', b'')
out('png', 'rgb8.png', png(4, 3, 8, 2, [bytes((x * 60 + y * 20) & 255 for x in range(12)) for y in range(3)]))
out('png', 'grey1.png', png(9, 2, 1, 0, [b'\xaa\x80', b'\x55\x00']))
out('png', 'grey8.png', png(3, 3, 8, 0, [b'\x00\x80\xff'] * 3))
out('png', 'rgb16.png', png(2, 2, 16, 2, [bytes(range(12)), bytes(range(12, 24))]))
out('png', 'palette.png', png(4, 1, 8, 3, [b'\x00\x01\x02\x01'],
                              extra=chunk(b'PLTE', b'\xff\x00\x00\x00\xff\x00\x00\x00\xff') + chunk(b'tRNS', b'\x80')))
out('png', 'rgba8.png', png(2, 2, 8, 6, [bytes(range(8)), bytes(range(8, 16))]))
# Adam7 passes of an 8x8 grey image: 1x1, 1x1, 2x1, 2x2, 4x2, 4x4, 8x4 sub-images.
adam7_rows = [bytes((x * 32 + y * 5) & 255 for x in range(w)) for w, h in
              ((1, 1), (1, 1), (2, 1), (2, 2), (4, 2), (4, 4), (8, 4)) for y in range(h)]
out('png', 'adam7.png', png(8, 8, 8, 0, adam7_rows, interlace=1))

# TGA: uncompressed true colour, RLE true colour, grey, colour-mapped; BMP 24-bit; HDR RLE.
def tga(kind, w, h, bpp, body, cmap=b'', cmap_spec=(0, 0, 0)):
    head = struct.pack('<BBBHHBHHHHBB', 0, 1 if cmap else 0, kind, cmap_spec[0], cmap_spec[1], cmap_spec[2], 0, 0, w, h, bpp, 0)
    return head + cmap + body
out('stb', 'rgb.tga', tga(2, 2, 2, 24, bytes(range(12))))
out('stb', 'rle.tga', tga(10, 4, 2, 24, b'\x83\x10\x20\x30' + b'\x03' + bytes(range(12))))
out('stb', 'grey.tga', tga(3, 3, 1, 8, b'\x00\x80\xff'))
out('stb', 'cmap.tga', tga(1, 2, 1, 8, b'\x00\x01', cmap=b'\x00\x00\xff\xff\x00\x00', cmap_spec=(0, 2, 24)))
def bmp(w, h):
    row = (w * 3 + 3) & ~3
    pixels = b''.join(bytes((x * 40 + y * 9) & 255 for x in range(w * 3)) + b'\x00' * (row - w * 3) for y in range(h))
    info = struct.pack('<IiiHHIIiiII', 40, w, h, 1, 24, 0, len(pixels), 2835, 2835, 0, 0)
    return b'BM' + struct.pack('<IHHI', 14 + 40 + len(pixels), 0, 0, 54) + info + pixels
out('stb', 'rgb.bmp', bmp(3, 2))
hdr_flat = b'#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 3\n' + bytes([128, 64, 32, 129] * 6)
out('stb', 'flat.hdr', hdr_flat)
# New-style RLE scanlines need a width of 8..32767: 8 pixels, each channel one run.
hdr_rle = b'#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 8\n' + b'\x02\x02\x00\x08' + b''.join(bytes([128 + 8, v]) for v in (100, 50, 25, 129))
out('stb', 'rle.hdr', hdr_rle)

# PFM: colour and grey, both byte orders.
out('pfm', 'rgb_le.pfm', b'PF\n2 2\n-1.0\n' + struct.pack('<12f', *[i / 4 for i in range(12)]))
out('pfm', 'grey_be.pfm', b'Pf\n3 1\n1.0\n' + struct.pack('>3f', 0.5, 1.5, -2.0))

# PLY: ASCII quad with normals and uv, binary little and big endian with a triangle fan.
ply_ascii = b'''ply
format ascii 1.0
comment seed
element vertex 4
property float x
property float y
property float z
property float nx
property float ny
property float nz
property float u
property float v
element face 1
property list uchar int vertex_indices
end_header
0 0 0 0 0 1 0 0
1 0 0 0 0 1 1 0
1 1 0 0 0 1 1 1
0 1 0 0 0 1 0 1
4 0 1 2 3
'''
out('ply', 'quad_ascii.ply', ply_ascii)
def ply_binary(order, fmt):
    head = ('ply\nformat %s 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n'
            'element face 1\nproperty list uchar uint vertex_indices\nend_header\n' % fmt).encode()
    body = struct.pack(order + '9f', 0, 0, 0, 1, 0, 0, 0, 1, 0) + struct.pack(order + 'B3I', 3, 0, 1, 2)
    return head + body
out('ply', 'tri_le.ply', ply_binary('<', 'binary_little_endian'))
out('ply', 'tri_be.ply', ply_binary('>', 'binary_big_endian'))

# Scenes: the directives and parameter types pbrt-v4 files use most.
scenes = {
'tiny.pbrt': '''LookAt 0 0 -3  0 0 0  0 1 0
Camera "perspective" "float fov" [ 45 ]
Film "rgb" "integer xresolution" [ 8 ] "integer yresolution" [ 8 ]
Sampler "halton" "integer pixelsamples" 4
WorldBegin
LightSource "point" "point3 from" [ 0.3 0.2 -1 ] "rgb I" [ 1 1 1 ]
Material "diffuse" "rgb reflectance" [ 0.5 0.5 0.5 ]
Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ] "point3 P" [ -1 -1 0  1 -1 0  1 1 0  -1 1 0 ]
''',
'lights.pbrt': '''WorldBegin
AttributeBegin
  AreaLightSource "diffuse" "blackbody L" [ 3000 ] "float scale" 2 "bool twosided" true
  Shape "disk" "float radius" 0.5
AttributeEnd
LightSource "spot" "point3 from" [0 4 0] "point3 to" [0 0 0] "float coneangle" 30 "float conedelta" 5 "spectrum I" "stdillum-D65"
LightSource "distant" "point3 to" [0 -1 0] "rgb L" [1 1 1] "float power" 3
LightSource "infinite" "rgb L" [0.1 0.1 0.2]
AttributeBegin
  Translate 0 1 0
  AreaLightSource "diffuse" "rgb L" [ 1 1 1 ]
  Shape "sphere" "float radius" 0.25
AttributeEnd
Shape "bilinearmesh" "point3 P" [0 0 0 1 0 0 0 0 1 1 0 1]
''',
'materials.pbrt': '''WorldBegin
Texture "checks" "spectrum" "checkerboard" "float uscale" 8 "float vscale" 8 "rgb tex1" [1 0 0] "rgb tex2" [0 0 1]
Texture "f" "float" "scale" "float scale" 0.5 "float tex" 1
MakeNamedMaterial "gold" "string type" "conductor" "spectrum eta" "metal-Au-eta" "spectrum k" "metal-Au-k" "float roughness" 0.1
MakeNamedMaterial "coat" "string type" "coateddiffuse" "texture reflectance" "checks" "float roughness" 0.2
Material "dielectric" "float eta" 1.5
Shape "sphere" "float radius" 1
NamedMaterial "gold"
ObjectBegin "thing"
  NamedMaterial "coat"
  Shape "trianglemesh" "integer indices" [0 1 2] "point3 P" [0 0 0 1 0 0 0 1 0] "normal N" [0 0 1 0 0 1 0 0 1] "point2 uv" [0 0 1 0 0 1]
ObjectEnd
AttributeBegin
  Transform [1 0 0 0 0 1 0 0 0 0 1 0 2 0 0 1]
  ObjectInstance "thing"
AttributeEnd
Material "mix" "string materials" [ "gold" "coat" ] "float amount" 0.3
Shape "cylinder" "float radius" 0.2 "float zmin" 0 "float zmax" 1
''',
'camera.pbrt': '''Scale -1 1 1
LookAt 0 5 10  0 0 0  0 1 0
Camera "perspective" "float fov" 30 "float lensradius" 0.01 "float focaldistance" 10
Film "rgb" "integer xresolution" 16 "integer yresolution" 12 "float cropwindow" [0.25 0.75 0 1] "string filename" "x.exr"
PixelFilter "gaussian"
Integrator "volpath" "integer maxdepth" 5
ColorSpace "srgb"
Option "bool disablepixeljitter" true
WorldBegin
CoordinateSystem "here"
AttributeBegin
  ReverseOrientation
  Rotate 45 0 1 0
  Shape "trianglemesh" "integer indices" [0 1 2] "point3 P" [0 0 0 1 0 0 0 1 0]
AttributeEnd
CoordSysTransform "here"
Attribute "shape" "float radius" 0.5
Shape "sphere"
''',
}
for name, text in scenes.items():
    out('scene', name, text.encode())

# EXR from penumbra's writer: an error image of two PFMs (ZIP-compressed scanlines, float RGB).
tmp = os.path.join(corpus, '..', 'seed-tmp.pfm')
with open(tmp, 'wb') as f:
    f.write(b'PF\n3 2\n-1.0\n' + struct.pack('<18f', *[i / 8 for i in range(18)]))
subprocess.run([penumbra, 'diff', tmp, tmp, '--error-image', os.path.join(corpus, 'exr', 'float_zip.exr')],
               check=False, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
os.remove(tmp)
os.makedirs(os.path.join(corpus, 'jpeg'), exist_ok=True)
subprocess.run([jpeg_tool, os.path.join(corpus, 'jpeg')], check=True)
