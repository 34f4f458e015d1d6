pub mod case;
pub mod compare;
pub mod inspect;
pub mod label_map;
