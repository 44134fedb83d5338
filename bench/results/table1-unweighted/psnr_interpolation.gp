# psnr_interpolation.png from psnr_interpolation.csv (written by fillgs); re-plot with: gnuplot psnr_interpolation.gp
set terminal pngcairo size 640,480 noenhanced font 'DejaVu Sans,10'
set datafile separator ','
set border 3 lc rgb '#404040'
set tics nomirror
set grid ytics lc rgb '#dddddd' lt 1
set style fill solid 0.85 noborder
set output 'psnr_interpolation.png'
set title 'interpolation PSNR per strategy (n3v)'
set xlabel ''
set ylabel 'PSNR (dB)'
set key off
set xtics rotate by -45 left scale 0 ('backbone' 0, 'no-refinement' 1)
set xrange [-0.6:1.6]
set yrange [*<0:*]
set offsets 0, 0, graph 0.08, 0
set boxwidth 0.7
plot 'psnr_interpolation.csv' skip 1 using 0:2 with boxes lc rgb '#3c78b4', '' skip 1 using 0:2:3 with labels offset 0,0.7 font ',9'
