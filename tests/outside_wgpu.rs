//! An outside WebGPU renderer: draws each golden's export with the
//! export's own `terrain.wgsl`, through wgpu on the first Vulkan adapter
//! (lavapipe in CI), reading only the export's files the way
//! docs/tutorials/verify-your-renderer.md and docs/reference/export-format.md
//! say (frame.glb's primitives in order, the `Frame` buffer's documented
//! offsets, effects.exr's maps as textures), and links nothing of
//! terraclip's library. `terraclip compare --mode exact` must pass on every
//! golden. Without an adapter the test is skipped, unless
//! `TERRACLIP_REQUIRE_GPU=1` (set by `.ci/run`).
//!
//! Its wgpu calls (targets, render pass, readback) repeat what
//! `src/gpu` does on purpose: an outside renderer shares no code with the
//! renderer it checks.
#![cfg(feature = "gpu")]

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;
use wgpu::util::DeviceExt;

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("terraclip-wgsl-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

fn terraclip(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_terraclip"))
        .args(args)
        .output()
        .unwrap();
    let text =
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    (out.status.success(), text)
}

fn json(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// The GLB's JSON and binary chunks (glTF 2.0, section 4.4).
fn read_glb(path: &Path) -> (Value, Vec<u8>) {
    let data = std::fs::read(path).unwrap();
    let u32_at = |i: usize| u32::from_le_bytes(data[i..i + 4].try_into().unwrap()) as usize;
    assert_eq!(u32_at(0), 0x4654_6C67, "glTF magic");
    let jlen = u32_at(12);
    let doc: Value = serde_json::from_slice(&data[20..20 + jlen]).unwrap();
    let blen = u32_at(20 + jlen);
    let start = 28 + jlen;
    (doc, data[start..start + blen].to_vec())
}

/// An accessor's float data: bytes, components, count.
fn accessor<'a>(doc: &Value, bin: &'a [u8], index: u64) -> (&'a [u8], u64, u32) {
    let a = &doc["accessors"][index as usize];
    let v = &doc["bufferViews"][a["bufferView"].as_u64().unwrap() as usize];
    assert_eq!(a["componentType"], 5126, "float accessors");
    let n = match a["type"].as_str().unwrap() {
        "SCALAR" => 1,
        "VEC2" => 2,
        "VEC3" => 3,
        _ => 4,
    };
    let count = a["count"].as_u64().unwrap();
    let off =
        (v["byteOffset"].as_u64().unwrap_or(0) + a["byteOffset"].as_u64().unwrap_or(0)) as usize;
    (&bin[off..off + (4 * n * count) as usize], n, count as u32)
}

/// effects.exr's layers, by name: (width, height, RGBA f32 texels) with
/// lightmap{k}'s L in R and normal{l}'s X, Y, Z in R, G, B.
fn effect_maps(path: &Path) -> Vec<(String, u32, u32, Vec<f32>)> {
    use exr::prelude::*;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_file(path)
        .unwrap();
    image
        .layer_data
        .into_iter()
        .map(|l| {
            let name = l.attributes.layer_name.as_ref().unwrap().to_string();
            let (w, h) = (l.size.0, l.size.1);
            let order: &[&str] = if name.starts_with("lightmap") {
                &["L"]
            } else {
                &["X", "Y", "Z"]
            };
            let mut rgba = vec![0f32; w * h * 4];
            for (k, want) in order.iter().enumerate() {
                let c = l
                    .channel_data
                    .list
                    .iter()
                    .find(|c| c.name.to_string() == *want)
                    .unwrap();
                let FlatSamples::F32(v) = &c.sample_data else {
                    panic!("f32 channels")
                };
                for (i, x) in v.iter().enumerate() {
                    rgba[i * 4 + k] = *x;
                }
            }
            (name, w as u32, h as u32, rgba)
        })
        .collect()
}

struct Gpu {
    device: wgpu::Device,
    queue: wgpu::Queue,
}

fn gpu() -> Option<Gpu> {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::VULKAN,
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let adapter = pollster::block_on(instance.request_adapter(&Default::default())).ok()?;
    let (device, queue) = pollster::block_on(adapter.request_device(&Default::default())).ok()?;
    Some(Gpu { device, queue })
}

/// Draws the export in `dir`; writes `out.png` and `out.f32` (depth, top
/// row first).
fn draw(g: &Gpu, dir: &Path, out: &Path) {
    let (d, q) = (&g.device, &g.queue);
    let frame = json(&dir.join("frame.json"));
    let camera = json(&dir.join("camera.json"));
    let (w, h) = (
        camera["width"].as_u64().unwrap() as u32,
        camera["height"].as_u64().unwrap() as u32,
    );
    let (doc, bin) = read_glb(&dir.join("frame.glb"));
    let varyings: Vec<String> = frame["varyings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["attribute"].as_str().unwrap().to_string())
        .collect();
    let source = std::fs::read_to_string(dir.join("terrain.wgsl")).unwrap();
    let module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: None,
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let effects: Vec<&str> = frame["effects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e.as_str().unwrap())
        .collect();
    let (shadows, mapped) = (
        effects.contains(&"shadows"),
        effects.contains(&"normal-map"),
    );
    // Bindings: 0 the Frame buffer; 1, 2 the lightmaps; 3, 4 the normal maps.
    let mut entries = vec![wgpu::BindGroupLayoutEntry {
        binding: 0,
        visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }];
    let tex = |binding| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: false },
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    };
    if shadows {
        entries.extend([tex(1), tex(2)]);
    }
    if mapped {
        entries.extend([tex(3), tex(4)]);
    }
    let bgl = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: None,
        entries: &entries,
    });
    let layout = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: None,
        bind_group_layouts: &[Some(&bgl)],
        immediate_size: 0,
    });
    let components: Vec<u64> = std::iter::once("POSITION".to_string())
        .chain(varyings.iter().cloned())
        .map(|name| {
            let prim = &doc["meshes"][0]["primitives"][0];
            accessor(&doc, &bin, prim["attributes"][&name].as_u64().unwrap()).1
        })
        .collect();
    let attrs: Vec<[wgpu::VertexAttribute; 1]> = components
        .iter()
        .enumerate()
        .map(|(i, &n)| {
            [wgpu::VertexAttribute {
                format: [
                    wgpu::VertexFormat::Float32,
                    wgpu::VertexFormat::Float32x2,
                    wgpu::VertexFormat::Float32x3,
                    wgpu::VertexFormat::Float32x4,
                ][n as usize - 1],
                offset: 0,
                shader_location: i as u32,
            }]
        })
        .collect();
    let buffers: Vec<Option<wgpu::VertexBufferLayout>> = components
        .iter()
        .zip(&attrs)
        .map(|(&n, a)| {
            Some(wgpu::VertexBufferLayout {
                array_stride: 4 * n,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: a,
            })
        })
        .collect();
    let pipeline = d.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: None,
        layout: Some(&layout),
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers: &buffers,
        },
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            cull_mode: None,
            ..Default::default()
        },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: wgpu::TextureFormat::Depth32Float,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Less),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs_main"),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format: wgpu::TextureFormat::Rgba8Unorm,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    });

    // effects.exr's maps, RGBA32F (WebGPU has no three-channel float).
    let maps: Vec<(String, wgpu::TextureView)> = if shadows || mapped {
        effect_maps(&dir.join("effects.exr"))
            .into_iter()
            .map(|(name, mw, mh, rgba)| {
                let t = d.create_texture_with_data(
                    q,
                    &wgpu::TextureDescriptor {
                        label: None,
                        size: wgpu::Extent3d {
                            width: mw,
                            height: mh,
                            depth_or_array_layers: 1,
                        },
                        mip_level_count: 1,
                        sample_count: 1,
                        dimension: wgpu::TextureDimension::D2,
                        format: wgpu::TextureFormat::Rgba32Float,
                        usage: wgpu::TextureUsages::TEXTURE_BINDING,
                        view_formats: &[],
                    },
                    wgpu::util::TextureDataOrder::LayerMajor,
                    &rgba
                        .iter()
                        .flat_map(|x| x.to_le_bytes())
                        .collect::<Vec<u8>>(),
                );
                (name, t.create_view(&Default::default()))
            })
            .collect()
    } else {
        vec![]
    };
    let map = |name: &str| &maps.iter().find(|m| m.0 == name).unwrap().1;

    let f32s = |v: &Value| -> Vec<f32> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap() as f32)
            .collect()
    };
    let shading = &frame["shading"];
    let fog = if shading["fog_colour"].is_null() {
        f32s(&frame["background"])
    } else {
        f32s(&shading["fog_colour"])
    };
    let origin = |level: u64| -> [i32; 2] {
        frame["levels"]
            .as_array()
            .unwrap()
            .iter()
            .find(|l| l["level"] == level)
            .map_or([0, 0], |l| {
                [
                    l["origin"][0].as_i64().unwrap() as i32,
                    l["origin"][1].as_i64().unwrap() as i32,
                ]
            })
    };
    let normal_origin = |level: u64| -> Option<[i32; 2]> {
        frame["normal_maps"]
            .as_array()
            .unwrap()
            .iter()
            .find(|m| m["level"] == level)
            .map(|m| {
                [
                    m["origin"][0].as_i64().unwrap() as i32,
                    m["origin"][1].as_i64().unwrap() as i32,
                ]
            })
    };
    let light_levels = frame["lightmap"]["levels"]
        .as_array()
        .map_or(0, |l| l.len() as u64);

    struct Draw {
        buffers: Vec<wgpu::Buffer>,
        count: u32,
        bind: wgpu::BindGroup,
    }
    let mut draws = vec![];
    for prim in doc["meshes"][0]["primitives"].as_array().unwrap() {
        let level = prim["extras"]["level"].as_u64().unwrap();
        let mut count = 0;
        let buffers: Vec<wgpu::Buffer> = std::iter::once("POSITION".to_string())
            .chain(varyings.iter().cloned())
            .map(|name| {
                let (bytes, _, n) =
                    accessor(&doc, &bin, prim["attributes"][&name].as_u64().unwrap());
                count = n;
                d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: None,
                    contents: bytes,
                    usage: wgpu::BufferUsages::VERTEX,
                })
            })
            .collect();
        // The Frame buffer, at the offsets terrain.wgsl's comment gives.
        let mut u = [0u8; 160];
        let mut put = |at: usize, bytes: &[u8]| u[at..at + bytes.len()].copy_from_slice(bytes);
        let le = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
        let vp: Vec<f32> = camera["view_proj"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(&f32s)
            .collect();
        put(0, &le(&vp));
        let palette = frame["level_palette"].as_array().unwrap();
        let tint: Vec<f32> = palette[level as usize % palette.len()]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| c.as_f64().unwrap() as f32 / 255.0)
            .collect();
        put(64, &le(&tint));
        put(76, &le(&[shading["ambient"].as_f64().unwrap() as f32]));
        put(80, &le(&f32s(&frame["sun_direction"])));
        put(
            92,
            &le(&[shading["specular_strength"].as_f64().unwrap() as f32]),
        );
        put(96, &le(&fog));
        put(
            108,
            &(shading["specular_squarings"].as_i64().unwrap() as i32).to_le_bytes(),
        );
        put(112, &le(&f32s(&shading["wire_colour"])));
        let scale = frame["lightmap"]["scale"].as_i64().unwrap_or(1) as i32;
        put(124, &scale.to_le_bytes());
        let o = origin(level);
        put(128, &o[0].to_le_bytes());
        put(132, &o[1].to_le_bytes());
        let fine = normal_origin(level).unwrap_or([0, 0]);
        let coarse = normal_origin(level + 1);
        put(136, &fine[0].to_le_bytes());
        put(140, &fine[1].to_le_bytes());
        put(144, &coarse.unwrap_or(fine)[0].to_le_bytes());
        put(148, &coarse.unwrap_or(fine)[1].to_le_bytes());
        let light_blend = level + 1 < light_levels;
        put(152, &u32::from(light_blend).to_le_bytes());
        put(156, &u32::from(coarse.is_some()).to_le_bytes());
        let ubuf = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: None,
            contents: &u,
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let mut bind = vec![wgpu::BindGroupEntry {
            binding: 0,
            resource: ubuf.as_entire_binding(),
        }];
        // A level's map and the next coarser one's (its own when there
        // is none), at bindings `first` and `first + 1`.
        let mut pair = |first: u32, fine: String, coarse: Option<String>| {
            let coarse = coarse.unwrap_or_else(|| fine.clone());
            for (k, name) in [fine, coarse].iter().enumerate() {
                bind.push(wgpu::BindGroupEntry {
                    binding: first + k as u32,
                    resource: wgpu::BindingResource::TextureView(map(name)),
                });
            }
        };
        if shadows {
            let fine = format!("lightmap{}", level.min(light_levels - 1));
            pair(
                1,
                fine,
                light_blend.then(|| format!("lightmap{}", level + 1)),
            );
        }
        if mapped {
            let next = coarse.map(|_| format!("normal{}", level + 1));
            pair(3, format!("normal{level}"), next);
        }
        let bind = d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &bgl,
            entries: &bind,
        });
        draws.push(Draw {
            buffers,
            count,
            bind,
        });
    }

    let target = |format| {
        d.create_texture(&wgpu::TextureDescriptor {
            label: None,
            size: wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        })
    };
    let colour = target(wgpu::TextureFormat::Rgba8Unorm);
    let depth = target(wgpu::TextureFormat::Depth32Float);
    let bg = f32s(&frame["background"]);
    let mut enc = d.create_command_encoder(&Default::default());
    {
        let (cv, dv) = (
            colour.create_view(&Default::default()),
            depth.create_view(&Default::default()),
        );
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: None,
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &cv,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color {
                        r: bg[0] as f64,
                        g: bg[1] as f64,
                        b: bg[2] as f64,
                        a: 1.0,
                    }),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &dv,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            ..Default::default()
        });
        pass.set_pipeline(&pipeline);
        for draw in &draws {
            pass.set_bind_group(0, &draw.bind, &[]);
            for (i, b) in draw.buffers.iter().enumerate() {
                pass.set_vertex_buffer(i as u32, b.slice(..));
            }
            pass.draw(0..draw.count, 0..1);
        }
    }
    // Read both attachments back, top row first.
    let row =
        (4 * w).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let readback = |t: &wgpu::Texture, aspect, enc: &mut wgpu::CommandEncoder| {
        let buf = d.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size: row as u64 * h as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        enc.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: t,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &buf,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(row),
                    rows_per_image: Some(h),
                },
            },
            wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
        );
        buf
    };
    let cbuf = readback(&colour, wgpu::TextureAspect::All, &mut enc);
    let dbuf = readback(&depth, wgpu::TextureAspect::DepthOnly, &mut enc);
    q.submit([enc.finish()]);
    let bytes = |buf: &wgpu::Buffer| -> Vec<u8> {
        buf.slice(..).map_async(wgpu::MapMode::Read, |_| {});
        d.poll(wgpu::PollType::wait_indefinitely()).unwrap();
        let view = buf.slice(..).get_mapped_range().unwrap();
        (0..h as usize)
            .flat_map(|y| view[y * row as usize..][..4 * w as usize].to_vec())
            .collect()
    };
    let rgba = bytes(&cbuf);
    image::RgbaImage::from_raw(w, h, rgba)
        .unwrap()
        .save(out.with_extension("png"))
        .unwrap();
    std::fs::write(out.with_extension("f32"), bytes(&dbuf)).unwrap();
}

#[test]
fn every_golden_drawn_from_its_exported_wgsl_is_exact() {
    let Some(g) = gpu() else {
        assert_ne!(
            std::env::var("TERRACLIP_REQUIRE_GPU").as_deref(),
            Ok("1"),
            "no Vulkan adapter, and TERRACLIP_REQUIRE_GPU=1"
        );
        eprintln!("skipped: no Vulkan adapter");
        return;
    };
    let mut names: Vec<String> = std::fs::read_dir("golden")
        .unwrap()
        .filter_map(|e| {
            let p = e.unwrap().path();
            let stem = p.file_stem()?.to_string_lossy().into_owned();
            (p.extension()? == "toml").then_some(stem)
        })
        .collect();
    names.sort();
    assert!(names.len() >= 15);
    let mut failed = vec![];
    for name in &names {
        let dir = tmp(name);
        let scene = format!("golden/{name}.toml");
        let (ok, text) = terraclip(&["export", &scene, "--out", dir.to_str().unwrap()]);
        assert!(ok, "{name}: {text}");
        let out = tmp(&format!("{name}-wgpu"));
        draw(&g, &dir, &out);
        let (png, f32) = (out.with_extension("png"), out.with_extension("f32"));
        let (ok, text) = terraclip(&[
            "compare",
            dir.to_str().unwrap(),
            "--image",
            png.to_str().unwrap(),
            "--depth",
            f32.to_str().unwrap(),
            "--mode",
            "exact",
        ]);
        eprintln!("{name}: {}", text.lines().next().unwrap_or(""));
        if !ok {
            failed.push(format!("{name}: {text}"));
        }
    }
    assert!(failed.is_empty(), "{failed:#?}");
}
