//! Headless device creation: no window, no surface. The adapter's own
//! limits are requested, because terrain textures (a 4320-wide map at
//! lightmap scale 2) exceed wgpu's portable defaults.

use crate::error::{Error, Result};

crate::names::named! {
    /// Which wgpu backend to open.
    pub enum Api ("graphics API") {
        /// Vulkan: lavapipe, or the GPU's driver.
        Vulkan => "vulkan",
        /// OpenGL through EGL, headless (no depth readback; unsupported).
        Gl => "gl",
    }
}

/// An open device.
pub struct Gpu {
    /// The wgpu device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// The adapter's name, driver and back end, for reports.
    pub info: wgpu::AdapterInfo,
    /// The graphics API in use (Vulkan, GL, …).
    pub api: Api,
    /// Whether the toroids' formats (R32Float, Rg32Float) may be storage
    /// textures, which the GPU update pass writes. GL's downlevel rules
    /// forbid it for Rg32Float, and creating one anyway is a validation
    /// error, which wgpu turns into a panic.
    pub toroid_storage: bool,
    /// Bytes written to buffers and textures since the device opened:
    /// every upload goes through [`Gpu::buffer_init`], [`Gpu::write_buffer`]
    /// or [`Gpu::write_texture`], so a frame's upload is the difference of
    /// this counter around it, counted from what was written rather than
    /// modelled.
    uploaded: std::sync::atomic::AtomicU64,
    /// Whether the device was opened with timestamp queries, so a render
    /// pass can be timed on the GPU's own clock.
    pub timestamps: bool,
}

impl Gpu {
    /// Opens the first adapter of `api`; an error (not a panic) if none.
    pub fn new(api: Api) -> Result<Gpu> {
        let backends = match api {
            Api::Vulkan => wgpu::Backends::VULKAN,
            Api::Gl => wgpu::Backends::GL,
        };
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends,
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        });
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            ..Default::default()
        }))
        .map_err(|e| {
            Error::value(
                "gpu",
                format!(
                    "no {api:?} adapter found ({e}); install a driver, e.g. \
                     `apt-get install mesa-vulkan-drivers libvulkan1` for lavapipe"
                ),
            )
        })?;
        let info = adapter.get_info();
        let toroid_storage = [
            wgpu::TextureFormat::R32Float,
            wgpu::TextureFormat::Rg32Float,
        ]
        .iter()
        .all(|&f| {
            adapter
                .get_texture_format_features(f)
                .allowed_usages
                .contains(wgpu::TextureUsages::STORAGE_BINDING)
        });
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let required_features = match timestamps {
            true => wgpu::Features::TIMESTAMP_QUERY,
            false => wgpu::Features::empty(),
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("terraclip"),
            required_limits: adapter.limits(),
            required_features,
            ..Default::default()
        }))
        .map_err(|e| Error::value("gpu", format!("{}: cannot open device: {e}", info.name)))?;
        if api == Api::Gl {
            first_vertex_provokes(&device);
        }
        Ok(Gpu {
            device,
            queue,
            info,
            api,
            toroid_storage,
            uploaded: Default::default(),
            timestamps,
        })
    }

    /// Bytes uploaded since the device opened (buffers and textures).
    pub fn uploaded(&self) -> u64 {
        self.uploaded.load(std::sync::atomic::Ordering::Relaxed)
    }

    fn count(&self, bytes: usize) {
        self.uploaded
            .fetch_add(bytes as u64, std::sync::atomic::Ordering::Relaxed);
    }

    /// A buffer created holding `bytes`, counted as uploaded. An empty
    /// `bytes` gets 16 zero bytes, because a binding must not be empty.
    pub(crate) fn buffer_init(
        &self,
        label: &str,
        bytes: &[u8],
        usage: wgpu::BufferUsages,
    ) -> wgpu::Buffer {
        use wgpu::util::DeviceExt;
        let pad = [0u8; 16];
        let contents = if bytes.is_empty() { &pad[..] } else { bytes };
        self.count(contents.len());
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
    }

    /// `queue.write_buffer`, counted as uploaded.
    pub(crate) fn write_buffer(&self, buffer: &wgpu::Buffer, offset: u64, bytes: &[u8]) {
        self.count(bytes.len());
        self.queue.write_buffer(buffer, offset, bytes);
    }

    /// `queue.write_texture`, counted as uploaded (the bytes given, padding
    /// of rows included, since that is what crosses to the device).
    pub(crate) fn write_texture(
        &self,
        dst: wgpu::TexelCopyTextureInfo,
        bytes: &[u8],
        layout: wgpu::TexelCopyBufferLayout,
        size: wgpu::Extent3d,
    ) {
        self.count(bytes.len());
        self.queue.write_texture(dst, bytes, layout, size);
    }

    /// Adapter name as the driver reports it.
    pub fn adapter(&self) -> String {
        format!("{} ({:?})", self.info.name, self.info.backend)
    }

    /// True on the stack docs/reference/raster-rules.md pins: lavapipe from Mesa 22.3.6 on
    /// x86-64 with FMA, through Vulkan. Parity must then be exact.
    pub fn exact_expected(&self) -> bool {
        let fma = crate::cpu::has_fma();
        self.api == Api::Vulkan
            && self.info.name.starts_with("llvmpipe")
            && self.info.driver_info.contains("Mesa 22.3.6")
            && fma
    }
}

/// Makes the first vertex of a triangle its provoking vertex on wgpu's GL
/// context, as Vulkan's is: wgpu leaves GL's default (the last), and
/// llvmpipe builds some triangles' depth planes from the provoking vertex.
/// On llvmpipe this took the goldens' differing pixels (wireframe aside)
/// from 44 to 29 and the exact goldens from 5 to 8 (docs/explanation/parity.md).
/// glow has no `glProvokingVertex`, so the entry point comes from EGL;
/// wgpu changes no provoking-vertex state afterwards.
fn first_vertex_provokes(device: &wgpu::Device) {
    type GetProc = unsafe extern "C" fn(*const libc::c_char) -> *const libc::c_void;
    type ProvokingVertex = unsafe extern "C" fn(u32);
    const FIRST_VERTEX_CONVENTION: u32 = 0x8E4D;
    // SAFETY: the hal device is wgpu's own GL device; the lock makes its
    // context current on this thread while the GL call runs, and the
    // symbols are EGL's and GL's documented entry points.
    unsafe {
        let Some(hal) = device.as_hal::<wgpu::hal::api::Gles>() else {
            return;
        };
        let _current = hal.context().lock();
        let egl = libc::dlopen(c"libEGL.so.1".as_ptr(), libc::RTLD_NOW);
        if egl.is_null() {
            return;
        }
        let get = libc::dlsym(egl, c"eglGetProcAddress".as_ptr());
        if get.is_null() {
            return;
        }
        let get: GetProc = std::mem::transmute(get);
        let f = get(c"glProvokingVertex".as_ptr());
        if !f.is_null() {
            let f: ProvokingVertex = std::mem::transmute(f);
            f(FIRST_VERTEX_CONVENTION);
        }
    }
}
