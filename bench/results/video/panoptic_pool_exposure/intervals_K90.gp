# intervals_K90.png from intervals_K90.csv (written by bench/pool_select_report.py); re-plot with: gnuplot intervals_K90.gp
set terminal pngcairo size 900,378 noenhanced font 'DejaVu Sans,10'
set datafile separator ','
set border 3 lc rgb '#404040'
set tics nomirror
set output 'intervals_K90.png'
set title 'Panoptic basketball, K = 90: 95 % intervals, affine PSNR (filled: excludes 0)'
set xlabel 'PSNR difference (dB)'
set key outside right top vertical
set grid xtics lc rgb '#dddddd' lt 1
set yrange [6.5:-0.5]
set ytics scale 0
set ytics ('positive control minus random' 0, 'FillGS minus negative' 1, 'FillGS minus random' 2, 'FillGS minus interpolation' 3, 'FillGS minus fisherrf' 4, 'FillGS minus coverage3d' 5, 'FillGS minus coverage4d' 6)
set xrange [-0.6344:0.6344]
set arrow from 0, graph 0 to 0, graph 1 nohead dt 2 lc rgb '#404040'
plot 'intervals_K90.csv' skip 1 using ($1 == 0 && $6 > 0.5 ? $3 : NaN):2:4:5 with xerrorbars pt 7 ps 1.3 lw 2 lc rgb '#3c78b4' title 'near', \
     'intervals_K90.csv' skip 1 using ($1 == 0 && $6 < 0.5 ? $3 : NaN):2:4:5 with xerrorbars pt 6 ps 1.3 lw 2 lc rgb '#3c78b4' notitle, \
     'intervals_K90.csv' skip 1 using ($1 == 1 && $6 > 0.5 ? $3 : NaN):2:4:5 with xerrorbars pt 7 ps 1.3 lw 2 lc rgb '#e0872c' title 'far', \
     'intervals_K90.csv' skip 1 using ($1 == 1 && $6 < 0.5 ? $3 : NaN):2:4:5 with xerrorbars pt 6 ps 1.3 lw 2 lc rgb '#e0872c' notitle
